#!/usr/bin/env python3
"""The arithmetic of scripts/score.py (`make score`'s summariser) on small hand-made runs.

Run by `make test` (rosunit's XML runner when given --gtest_output=xml:FILE), or alone:
/usr/bin/python3 test/test_score.py
"""
import math
import os
import re
import sys
import tempfile
import unittest

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "scripts"))
import score  # noqa: E402

HEADER = ("frame,method,matches,valid,yaw_est_deg,yaw_true_deg,rot_err_deg,yaw_err_deg,rate_dps,estimate_ms,"
          "rate_err_dps,nees,err_x_deg,err_y_deg,err_z_deg,error\n")


def write_csv(path, rows):
    """rows: (frame, method, valid, rot_err, nees, (ex, ey, ez)); other columns left empty."""
    with open(path, "w") as f:
        f.write(HEADER)
        for frame, method, valid, err, nees, vec in rows:
            f.write(f"{frame},{method},100,{valid},,,{err},,,,,{nees},{vec[0]},{vec[1]},{vec[2]},\"\"\n")


class ScoreArithmetic(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="test_score_")

    def run_of(self, rows):
        path = os.path.join(self.dir, "run.csv")
        write_csv(path, rows)
        return score.read_frames(path)

    def test_bound_is_the_one_metrics_h_defines(self):
        with open(score.METRICS_HEADER) as f:
            text = f.read()
        self.assertIn("kChiSquare3Dof99", text)
        defined = float(re.search(r"kChiSquare3Dof99\s*=\s*([0-9.]+)", text).group(1))
        self.assertEqual(score.chi_square_bound(), defined)

    def test_pooled_figures_match_metrics_cpp_definitions(self):
        # Two seeds of one method: errors 3, 4 (seed 1) and 0, 0, 5 (seed 2, one invalid frame, which
        # the CSV already scores as the identity).
        seed1 = self.run_of([(1, "vote", 1, 3.0, 2.0, (3, 0, 0)), (2, "vote", 1, 4.0, 20.0, (0, 4, 0))])["vote"]
        seed2 = self.run_of([(1, "vote", 1, 0.0, 1.0, (0, 0, 0)), (2, "vote", 0, 0.0, "", (0, 0, 0)),
                             (3, "vote", 1, 5.0, 12.0, (0, 0, 5))])["vote"]
        s = score.summarise([("1", seed1), ("2", seed2)], debias=False, bound=11.345)
        self.assertEqual(s["frames"], 5)
        self.assertEqual(s["invalid"], 1)
        self.assertAlmostEqual(s["rmse"], math.sqrt((9 + 16 + 0 + 0 + 25) / 5))
        self.assertAlmostEqual(s["max"], 5.0)
        self.assertAlmostEqual(s["p95"], np.percentile([3, 4, 0, 0, 5], 95))
        self.assertAlmostEqual(s["nees_mean"], (2 + 20 + 1 + 12) / 4)  # the invalid frame has no NEES
        self.assertAlmostEqual(s["nees_beyond99"], 2 / 4)
        self.assertAlmostEqual(s["seed_rmse"]["1"], math.sqrt(12.5))
        self.assertAlmostEqual(s["seed_rmse"]["2"], math.sqrt(25 / 3))

    def test_gyro_bias_is_removed_per_axis(self):
        # A constant error of (1, -2, 0.5) deg plus +-0.1 about x: only the spread remains.
        rows = [(k, "vote", 1, 99.0, "", (1 + (0.1 if k % 2 else -0.1), -2, 0.5)) for k in range(1, 9)]
        s = score.summarise([("1", self.run_of(rows)["vote"])], debias=True, bound=11.345)
        self.assertAlmostEqual(s["rmse"], 0.1)
        self.assertAlmostEqual(s["max"], 0.1)
        self.assertTrue(math.isnan(s["nees_mean"]))

    def test_ratio_to_best_peer_and_over_cases(self):
        ratios = score.ratios_to_best_peer({"vote": 1.0, "a": 2.0, "b": 4.0})
        self.assertAlmostEqual(ratios["vote"], 0.5)
        self.assertAlmostEqual(ratios["a"], 2.0)
        self.assertAlmostEqual(ratios["b"], 4.0)
        summary = score.over_cases({"x": 0.5, "y": 2.0, "z": 8.0})
        self.assertAlmostEqual(summary["geomean"], 2.0)
        self.assertAlmostEqual(summary["worst"], 8.0)
        self.assertEqual(summary["worst_case"], "z")

    def test_seed_spread(self):
        def figures(rmse_by_seed):
            return {"rmse": float(np.sqrt(np.mean(np.square(list(rmse_by_seed.values()))))), "seed_rmse": rmse_by_seed}
        per_case = {"c1": {"vote": figures({"1": 1.0, "2": 2.0}), "a": figures({"1": 2.0, "2": 2.0})},
                    "c2": {"vote": figures({"1": 1.0, "2": 1.0}), "a": figures({"1": 4.0, "2": 4.0})}}
        spread = score.seed_spread(per_case, ["1", "2"])
        # Seed 1: ratios 0.5 and 0.25; seed 2: 1.0 and 0.25.
        self.assertAlmostEqual(spread["geomean_per_seed"][0], math.sqrt(0.5 * 0.25))
        self.assertAlmostEqual(spread["geomean_per_seed"][1], math.sqrt(1.0 * 0.25))
        pooled = math.sqrt(math.sqrt(2.5) / 2.0 * 0.25)
        self.assertAlmostEqual(spread["relative"], (0.5 - math.sqrt(0.125)) / pooled)
        # Per case: (2 - 1) / 1.5 and the floor for the case both seeds agree on.
        self.assertAlmostEqual(spread["per_case_rmse_geomean"], math.sqrt((1 / 1.5) * score.SPREAD_FLOOR))
        self.assertTrue(math.isnan(score.seed_spread(per_case, ["1"])["relative"]))

    def test_ablations_are_nobodys_peer_and_vote_is_not_theirs(self):
        rmse = {"vote": 1.0, "a": 2.0, "vote-without-valley": 0.5}
        ratios = score.ratios_to_best_peer(rmse)
        self.assertAlmostEqual(ratios["vote"], 0.5)  # against a, not against its own ablation
        self.assertAlmostEqual(ratios["a"], 2.0)
        self.assertAlmostEqual(ratios["vote-without-valley"], 0.25)  # against a, not against vote

    def test_ablation_verdict_against_the_seed_spread(self):
        def case(vote, without_x, without_y, peer):
            f = lambda r: {"rmse": r, "nees_mean": 2.0, "nees_beyond99": 0.01}
            return {"vote": f(vote), "vote-without-x": f(without_x), "vote-without-y": f(without_y), "a": f(peer)}
        per_case = {"c1": case(1.0, 2.0, 1.01, 2.0), "c2": case(1.0, 1.5, 0.99, 2.0)}  # all honest
        methods = ["vote", "a", "vote-without-x", "vote-without-y"]
        ratios = {c: score.ratios_to_best_peer({m: f["rmse"] for m, f in v.items()}) for c, v in per_case.items()}
        per_method = {m: score.over_cases({c: ratios[c][m] for c in per_case}) for m in methods}
        rows = score.ablation_rows(methods, per_case, per_method, {"relative": 0.1})
        by_part = {r["part"]: r for r in rows}
        self.assertEqual(set(by_part), {"x", "y"})
        self.assertEqual(by_part["x"]["verdict"], "pays")  # geomean 0.87 against vote's 0.5
        self.assertAlmostEqual(by_part["x"]["vs_vote"]["geomean"], math.sqrt(2.0 * 1.5))
        self.assertEqual(by_part["x"]["vs_vote"]["worst_case"], "c1")
        self.assertEqual(by_part["y"]["verdict"], "within the spread")

    def test_a_covariance_part_pays_when_its_removal_makes_cases_overconfident(self):
        bound = score.metrics_constant("kHonestNeesMeanMax")
        def f(rmse, nees):
            return {"rmse": rmse, "nees_mean": nees, "nees_beyond99": 0.0}
        per_case = {"c1": {"vote": f(1.0, 3.0), "vote-without-z": f(1.0, 2 * bound), "a": f(2.0, math.nan)},
                    "c2": {"vote": f(1.0, 3.0), "vote-without-z": f(1.0, 3.0), "a": f(2.0, math.nan)}}
        methods = ["vote", "a", "vote-without-z"]
        ratios = {c: score.ratios_to_best_peer({m: x["rmse"] for m, x in v.items()}) for c, v in per_case.items()}
        per_method = {m: score.over_cases({c: ratios[c][m] for c in per_case}) for m in methods}
        self.assertEqual(score.overconfident_cases(per_case, "vote-without-z"), ["c1"])
        rows = score.ablation_rows(methods, per_case, per_method, {"relative": 0.1})
        self.assertEqual(rows[0]["verdict"], "pays (covariance)")

    def test_goals_report_their_bounds_what_was_measured_and_whether_met(self):
        def f(rmse, nees=2.0):
            return {"rmse": rmse, "nees_mean": nees, "nees_beyond99": 0.0}
        peer = score.ROLLING_SHUTTER_PEER
        per_case = {"handheld": {"vote": f(1.1), peer: f(1.0)},                  # ratio 1.1: above 1
                    "handheld_rs_15hz": {"vote": f(1.0), peer: f(2.0)},          # a room, 0.5
                    "dim_hand_rs_noise6": {"vote": f(3.0, 50.0), peer: f(2.0), "a": f(6.0)},  # a room, 1.5
                    "hand_rs_720p": {"vote": f(1.0), peer: f(4.0)},              # a room, 0.25
                    "drone_near_rs": {"vote": f(1.0), "a": f(8.0)}}              # not a room
        methods = ["vote", peer, "a"]
        ratios = {c: score.ratios_to_best_peer({m: x["rmse"] for m, x in v.items()}) for c, v in per_case.items()}
        per_method = {m: score.over_cases({c: ratios[c].get(m, math.nan) for c in per_case}) for m in methods}
        g = score.goals(per_case, ratios, per_method)
        expected_geomean = math.exp(np.mean(np.log([1.1, 0.5, 1.5, 0.25, 0.125])))
        self.assertAlmostEqual(g["geomean"]["value"], expected_geomean)
        self.assertEqual(g["geomean"]["max"], score.GOAL_GEOMEAN_MAX)
        self.assertEqual(g["geomean"]["met"], expected_geomean <= score.GOAL_GEOMEAN_MAX)
        self.assertFalse(g["every_case"]["met"])
        self.assertEqual(list(g["every_case"]["above"]), ["dim_hand_rs_noise6", "handheld"])  # worst first
        self.assertEqual(set(g["rolling_shutter_rooms"]["vote_over_peer"]),
                         {"handheld_rs_15hz", "dim_hand_rs_noise6", "hand_rs_720p"})
        self.assertAlmostEqual(g["rolling_shutter_rooms"]["vote_over_peer"]["dim_hand_rs_noise6"], 1.5)
        self.assertFalse(g["rolling_shutter_rooms"]["met"])
        self.assertEqual(g["overconfident_cases"], ["dim_hand_rs_noise6"])
        # Without the rooms' peer in the run, that goal is not measured rather than met.
        without_peer = {c: {m: x for m, x in v.items() if m != peer} for c, v in per_case.items()}
        self.assertIsNone(score.goals(without_peer, ratios, per_method)["rolling_shutter_rooms"]["met"])

    def test_the_goals_docs_state_are_the_goals_the_score_judges(self):
        with open(os.path.join(REPO, "doc", "evaluation.md")) as f:
            text = f.read()
        self.assertIn(f"≤ {score.GOAL_GEOMEAN_MAX}", text)
        self.assertIn(f"≤ {score.GOAL_EVERY_CASE_MAX} on every case", text)
        self.assertIn(f"`{score.ROLLING_SHUTTER_PEER}`", text)


if __name__ == "__main__":
    output = [a for a in sys.argv[1:] if a.startswith("--gtest_output=xml:")]
    if output:
        import rosunit
        suite = unittest.TestLoader().loadTestsFromTestCase(ScoreArithmetic)
        result = rosunit.create_xml_runner("visual_gyro", "test_score",
                                           results_file=output[0].split(":", 1)[1]).run(suite)
        sys.exit(0 if result.wasSuccessful() else 1)
    unittest.main()
