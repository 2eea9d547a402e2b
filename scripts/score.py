#!/usr/bin/env python3
"""Summarises `make score`: every method on every case, pooled over estimator seeds.

Input: a manifest (tab-separated: case, seed, per-frame CSV of `evaluate --csv`, its log with the
JSON lines). Per case and method, over the frames of every seed together:
  - rmse, max: sqrt(mean(rot_err_deg^2)) and max(rot_err_deg) over the frames with a reference, as
    metrics.cpp's AccuracyAccumulator computes rot_rmse_deg / rot_max_deg (an invalid estimate is
    scored as the identity there, so its row's rot_err_deg already counts it);
  - p95: the 95th percentile of rot_err_deg (numpy's linear interpolation);
  - invalid: frames with valid = 0;
  - nees_mean, nees_beyond99: mean NEES and the share above metrics.h's kChiSquare3Dof99 (read from
    that header, not copied) over the frames with a NEES, as AccuracyAccumulator does.
Where the reference is the gyro (`truth` = gyro in evaluate's JSON: euroc_v101_static), its constant
bias is removed: per run (case, seed, method) the per-axis mean of the error vector
(err_x/y/z_deg: the rotation vector of R_est^T R_true) is subtracted, and rmse / p95 / max are those
of the norm of what is left (the per-axis spread). NEES is not defined against a gyro.

Per method, per case: its pooled rmse over the best pooled rmse of the other methods (ratio < 1: it
beats every other method); over the cases the geometric mean and the worst ratio. The seed-to-seed
spread: vote's geometric mean ratio computed from each seed alone, (max - min) / pooled; and the
geometric mean over cases of vote's per-case (max - min) / mean of its per-seed RMSE (each floored
at 0.1 %, so a case that every seed gets equally right does not zero the product).

Writes score.md, score.csv, score.png and score.json in --out; prints the JSON on the last line.
"""
import argparse
import csv
import json
import math
import os
import re
import sys
from collections import defaultdict
from functools import lru_cache

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
METRICS_HEADER = os.path.join(REPO, "src", "eval", "metrics.h")
SPREAD_FLOOR = 1e-3
REFERENCE_METHOD = "vote"
ABLATION_PREFIX = "vote-without-"
# The goals the score judges (doc/evaluation.md, "Goals"): vote's RMSE over the best other method's,
# as a geometric mean over cases and on every case; on the hand-held rolling-shutter rooms, vote's
# RMSE over that of the peer that plain rotation-only RANSAC is (cases named handheld_rs*,
# dim_hand_rs*, hand_rs_*).
GOAL_GEOMEAN_MAX = 0.8
GOAL_EVERY_CASE_MAX = 1.0
ROLLING_SHUTTER_ROOMS = re.compile(r"(^|_)hand(held)?_rs")
ROLLING_SHUTTER_PEER = "opengv_rotation_only"
GOAL_ROLLING_SHUTTER_MAX = 1.0


def is_ablation(method):
    """vote-without-<part>: the vote method with one part off (evaluate --list-ablations)."""
    return method.startswith(ABLATION_PREFIX)


@lru_cache(maxsize=None)
def metrics_constant(name, header=METRICS_HEADER):
    """A constant as metrics.h defines it (one source of truth)."""
    with open(header) as f:
        match = re.search(name + r"\s*=\s*([0-9.eE+-]+)\s*;", f.read())
    if not match:
        sys.exit(f"[score] {name} not found in {header}")
    return float(match.group(1))


def chi_square_bound(header=METRICS_HEADER):
    """kChiSquare3Dof99 of metrics.h."""
    return metrics_constant("kChiSquare3Dof99", header)


def overconfident_cases(per_case, method):
    """Cases where `method`'s covariance is over-confident: NEES mean above metrics.h's
    kHonestNeesMeanMax or a share beyond the 99 % bound above kHonestBeyond99Max."""
    nees_max, beyond_max = metrics_constant("kHonestNeesMeanMax"), metrics_constant("kHonestBeyond99Max")
    return sorted(c for c, f in per_case.items() if method in f and
                  (f[method]["nees_mean"] > nees_max or f[method]["nees_beyond99"] > beyond_max))


def number(text):
    return float(text) if text not in ("", "nan", "-nan", "inf") else math.nan


def read_frames(path):
    """Per method: arrays of rot_err_deg, valid, nees and the error vectors [deg] of one run."""
    rows = defaultdict(lambda: {"err": [], "valid": [], "nees": [], "vec": []})
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            r = rows[row["method"]]
            r["err"].append(number(row["rot_err_deg"]))
            r["valid"].append(row["valid"] == "1")
            r["nees"].append(number(row["nees"]))
            r["vec"].append([number(row[k]) for k in ("err_x_deg", "err_y_deg", "err_z_deg")])
    return {m: {k: np.array(v, dtype=float if k != "valid" else bool) for k, v in r.items()} for m, r in rows.items()}


def read_truth(log):
    """The reference kind evaluate reports (`truth` of its JSON lines): poses, gyro, ..."""
    with open(log) as f:
        for line in f:
            if line.startswith("{"):
                return json.loads(line).get("truth", "")
    return ""


def scored_errors(run, debias):
    """Errors [deg] of one run that count: rot_err_deg, or the bias-free error norms (gyro)."""
    if not debias:
        return run["err"][np.isfinite(run["err"])]
    vec = run["vec"][np.all(np.isfinite(run["vec"]), axis=1)]
    if len(vec) == 0:
        return np.zeros(0)
    return np.linalg.norm(vec - vec.mean(axis=0), axis=1)


def rmse(errors):
    return float(math.sqrt(np.mean(errors ** 2))) if len(errors) else math.nan


def summarise(seeded_runs, debias, bound):
    """Pooled figures of one case and method over its runs, [(seed, run)]."""
    runs = [r for _, r in seeded_runs]
    errors = np.concatenate([scored_errors(r, debias) for r in runs])
    nees = np.concatenate([r["nees"] for r in runs])
    nees = nees[np.isfinite(nees)]
    return {
        "frames": int(sum(len(r["valid"]) for r in runs)),
        "invalid": int(sum(int((~r["valid"]).sum()) for r in runs)),
        "rmse": rmse(errors),
        "p95": float(np.percentile(errors, 95)) if len(errors) else math.nan,
        "max": float(errors.max()) if len(errors) else math.nan,
        "nees_mean": float(nees.mean()) if len(nees) else math.nan,
        "nees_beyond99": float((nees > bound).mean()) if len(nees) else math.nan,
        "seed_rmse": {seed: rmse(scored_errors(r, debias)) for seed, r in seeded_runs},
    }


def is_peer(method, other):
    """Whether `other` counts among `method`'s peers: every other method, but never an ablation
    (vote without one part), and the vote method is no peer of its own ablations."""
    if other == method or is_ablation(other):
        return False
    return not (is_ablation(method) and other == REFERENCE_METHOD)


def ratios_to_best_peer(rmse_by_method):
    """Per method: its RMSE over the least RMSE of its peers (NaN without a peer)."""
    out = {}
    for m, value in rmse_by_method.items():
        peers = [v for p, v in rmse_by_method.items() if is_peer(m, p) and math.isfinite(v)]
        out[m] = value / max(min(peers), 1e-12) if peers and math.isfinite(value) else math.nan
    return out


def geomean(values):
    values = [v for v in values if math.isfinite(v) and v > 0]
    return math.exp(sum(math.log(v) for v in values) / len(values)) if values else math.nan


def over_cases(ratio_by_case):
    """Geometric mean and worst ratio over cases, and the worst case."""
    finite = {c: r for c, r in ratio_by_case.items() if math.isfinite(r)}
    if not finite:
        return {"geomean": math.nan, "worst": math.nan, "worst_case": ""}
    worst_case = max(finite, key=finite.get)
    return {"geomean": geomean(finite.values()), "worst": finite[worst_case], "worst_case": worst_case}


def seed_spread(per_case, seeds, method=REFERENCE_METHOD):
    """How far `method`'s score moves from one estimator seed to another (see the module doc)."""
    if len(seeds) < 2:
        return {"seeds": len(seeds), "geomean_per_seed": [], "relative": math.nan, "per_case_rmse_geomean": math.nan}
    per_seed = []
    for seed in seeds:
        ratios = []
        for figures in per_case.values():
            by_method = {m: f["seed_rmse"][seed] for m, f in figures.items() if seed in f["seed_rmse"]}
            if method in by_method:
                ratios.append(ratios_to_best_peer(by_method)[method])
        per_seed.append(geomean(ratios))
    pooled = over_cases({c: ratios_to_best_peer({m: f["rmse"] for m, f in figures.items()}).get(method, math.nan)
                         for c, figures in per_case.items()})["geomean"]
    case_spreads = []
    for figures in per_case.values():
        values = [v for v in figures.get(method, {}).get("seed_rmse", {}).values() if math.isfinite(v)]
        if len(values) >= 2 and np.mean(values) > 0:
            case_spreads.append(max((max(values) - min(values)) / np.mean(values), SPREAD_FLOOR))
    return {"seeds": len(seeds), "geomean_per_seed": per_seed,
            "relative": (max(per_seed) - min(per_seed)) / pooled if pooled > 0 else math.nan,
            "per_case_rmse_geomean": geomean(case_spreads)}


def ablation_rows(methods, per_case, per_method, spread):
    """Per ablation: its score beside vote's, its RMSE over vote's per case (geometric mean, worst),
    its NEES mean over cases, its over-confident cases, and a verdict: the part pays when removing
    it worsens the geometric mean vs the best peer by more than the seed-to-seed spread ((max - min)
    / pooled, times vote's geomean), or, for a part that leaves the rotations as they are (a part
    of the covariance), when removing it makes more cases over-confident."""
    vote = per_method.get(REFERENCE_METHOD, {}).get("geomean", math.nan)
    margin = spread["relative"] * vote if math.isfinite(spread["relative"]) else 0.0
    reference_overconfident = len(overconfident_cases(per_case, REFERENCE_METHOD))
    rows = []
    for m in methods:
        if not is_ablation(m):
            continue
        vs_vote = {c: f[m]["rmse"] / max(f[REFERENCE_METHOD]["rmse"], 1e-12)
                   for c, f in per_case.items() if m in f and REFERENCE_METHOD in f}
        nees = [f[m]["nees_mean"] for f in per_case.values() if m in f and math.isfinite(f[m]["nees_mean"])]
        beyond = [f[m]["nees_beyond99"] for f in per_case.values() if m in f and math.isfinite(f[m]["nees_beyond99"])]
        g = per_method[m]["geomean"]
        overconfident = overconfident_cases(per_case, m)
        verdict = ("pays" if g - vote > margin else "costs" if vote - g > margin else "within the spread")
        if verdict == "within the spread" and len(overconfident) > reference_overconfident:
            verdict = "pays (covariance)"
        rows.append({"part": m[len(ABLATION_PREFIX):], "geomean": g, "worst": per_method[m]["worst"],
                     "vs_vote": over_cases(vs_vote), "nees_mean": float(np.mean(nees)) if nees else math.nan,
                     "nees_beyond99": float(np.mean(beyond)) if beyond else math.nan,
                     "overconfident": overconfident, "verdict": verdict})
    return rows


def goals(per_case, ratios, per_method):
    """The goals as this run measures them: each with its bound, what was measured and whether it
    is met (None where the run lacks what it needs), and vote's over-confident cases beside them."""
    vote = per_method.get(REFERENCE_METHOD, {}).get("geomean", math.nan)
    vote_ratios = {c: r[REFERENCE_METHOD] for c, r in ratios.items()
                   if REFERENCE_METHOD in r and math.isfinite(r[REFERENCE_METHOD])}
    above = {c: v for c, v in vote_ratios.items() if v > GOAL_EVERY_CASE_MAX}
    rooms = {c: f[REFERENCE_METHOD]["rmse"] / max(f[ROLLING_SHUTTER_PEER]["rmse"], 1e-12)
             for c, f in per_case.items() if ROLLING_SHUTTER_ROOMS.search(c) and REFERENCE_METHOD in f
             and ROLLING_SHUTTER_PEER in f and math.isfinite(f[REFERENCE_METHOD]["rmse"])
             and math.isfinite(f[ROLLING_SHUTTER_PEER]["rmse"])}
    return {
        "geomean": {"max": GOAL_GEOMEAN_MAX, "value": vote,
                    "met": bool(vote <= GOAL_GEOMEAN_MAX) if math.isfinite(vote) else None},
        "every_case": {"max": GOAL_EVERY_CASE_MAX, "above": dict(sorted(above.items(), key=lambda kv: -kv[1])),
                       "met": not above if vote_ratios else None},
        "rolling_shutter_rooms": {"peer": ROLLING_SHUTTER_PEER, "max": GOAL_ROLLING_SHUTTER_MAX,
                                  "vote_over_peer": rooms,
                                  "met": all(v <= GOAL_ROLLING_SHUTTER_MAX for v in rooms.values()) if rooms else None},
        "overconfident_cases": overconfident_cases(per_case, REFERENCE_METHOD),
    }


def goals_markdown(g):
    met = lambda v: "met" if v else "not met" if v is not None else "not measured"
    above = ", ".join(f"{c} {fmt(v, 2)}" for c, v in g["every_case"]["above"].items()) or "none"
    rooms = ", ".join(f"{c} {fmt(v, 2)}" for c, v in g["rolling_shutter_rooms"]["vote_over_peer"].items()) or "none"
    return ["## Goals", "",
            f"- Geometric mean of `{REFERENCE_METHOD}`'s ratio ≤ {g['geomean']['max']}: {fmt(g['geomean']['value'])}, "
            f"{met(g['geomean']['met'])}.",
            f"- Ratio ≤ {g['every_case']['max']} on every case: {met(g['every_case']['met'])}; above it: {above}.",
            f"- Hand-held rolling-shutter rooms, `{REFERENCE_METHOD}` at least as accurate as "
            f"`{g['rolling_shutter_rooms']['peer']}` (RMSE ratio ≤ {g['rolling_shutter_rooms']['max']}): "
            f"{met(g['rolling_shutter_rooms']['met'])}; "
            f"{rooms}.",
            f"- Over-confident cases of `{REFERENCE_METHOD}` (not a goal of the score; see the ablation's rule): "
            f"{', '.join(g['overconfident_cases']) or 'none'}.", ""]


def fmt(value, digits=3):
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value:.{digits}f}"


def ablation_markdown(rows, per_case, per_method):
    if not rows:
        return []
    nees = [f[REFERENCE_METHOD]["nees_mean"] for f in per_case.values()
            if REFERENCE_METHOD in f and math.isfinite(f[REFERENCE_METHOD]["nees_mean"])]
    vote = per_method.get(REFERENCE_METHOD, {})
    lines = ["## Ablation: vote without one part", "",
             "| without | geometric mean vs best peer | worst | RMSE / vote's: geometric mean | worst (case) "
             "| NEES mean over cases | over-confident cases | verdict |", "|---|---|---|---|---|---|---|---|",
             f"| (nothing: vote) | {fmt(vote.get('geomean', math.nan))} | {fmt(vote.get('worst', math.nan))} | 1 | 1 "
             f"| {fmt(float(np.mean(nees)) if nees else math.nan, 2)} "
             f"| {len(overconfident_cases(per_case, REFERENCE_METHOD))} | |"]
    for r in rows:
        lines.append(f"| {r['part']} | {fmt(r['geomean'])} | {fmt(r['worst'])} | {fmt(r['vs_vote']['geomean'])} "
                     f"| {fmt(r['vs_vote']['worst'], 2)} ({r['vs_vote']['worst_case']}) | {fmt(r['nees_mean'], 2)} "
                     f"| {len(r['overconfident'])} | {r['verdict']} |")
    return lines + [""]


def write_markdown(path, header, cases, methods, per_case, ratios, per_method, spread, notes, ablation):
    lines = ["# make score", "", *header, ""]
    lines += goals_markdown(goals(per_case, ratios, per_method))
    lines += ["## Per method: RMSE over the best other method's, per case", "",
              "| method | geometric mean | worst | worst case |", "|---|---|---|---|"]
    for m in methods:
        s = per_method[m]
        lines.append(f"| {m} | {fmt(s['geomean'])} | {fmt(s['worst'])} | {s['worst_case']} |")
    lines += ["", f"Seed-to-seed spread of `{REFERENCE_METHOD}` ({spread['seeds']} seeds): its geometric mean from each "
              f"seed alone {', '.join(fmt(g) for g in spread['geomean_per_seed']) or '-'}, (max - min) / pooled "
              f"{fmt(spread['relative'])}; per case (max - min) / mean of the seeds' RMSE, geometric mean over cases "
              f"{fmt(spread['per_case_rmse_geomean'])}.", ""]
    lines += ablation_markdown(ablation, per_case, per_method)
    lines += ["## Ratio to the best other method, per case", "",
              "| case | " + " | ".join(methods) + " |", "|---|" + "---|" * len(methods)]
    for c in cases:
        lines.append(f"| {c} | " + " | ".join(fmt(ratios[c].get(m, math.nan), 2) for m in methods) + " |")
    lines += ["", "## Per case: rotation error RMSE / p95 / max [deg], invalid frames, NEES mean; share beyond "
              "the 99 % bound", ""]
    for c in cases:
        lines += [f"### {c}", "", f"{notes[c]}", "", "| method | RMSE | p95 | max | invalid / frames | NEES mean | beyond 99 % |",
                  "|---|---|---|---|---|---|---|"]
        for m in methods:
            f = per_case[c].get(m)
            if f is None:
                continue
            beyond = fmt(100.0 * f["nees_beyond99"], 1) + " %" if math.isfinite(f["nees_beyond99"]) else "-"
            lines.append(f"| {m} | {fmt(f['rmse'])} | {fmt(f['p95'])} | {fmt(f['max'])} | {f['invalid']} / {f['frames']} "
                         f"| {fmt(f['nees_mean'], 2)} | {beyond} |")
        lines.append("")
    with open(path, "w") as f:
        f.write("\n".join(lines))


def write_csv(path, cases, methods, per_case, ratios):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["case", "method", "frames", "invalid", "rmse_deg", "p95_deg", "max_deg", "nees_mean",
                    "nees_beyond99", "ratio_to_best_peer", "seed_rmse_deg"])
        for c in cases:
            for m in methods:
                x = per_case[c].get(m)
                if x is None:
                    continue
                w.writerow([c, m, x["frames"], x["invalid"], fmt(x["rmse"], 6), fmt(x["p95"], 6), fmt(x["max"], 6),
                            fmt(x["nees_mean"], 4), fmt(x["nees_beyond99"], 4), fmt(ratios[c].get(m, math.nan), 4),
                            ";".join(f"{s}:{fmt(v, 6)}" for s, v in x["seed_rmse"].items())])


def write_plot(path, cases, methods, ratios, title):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(max(8.0, 0.55 * len(cases) + 3.0), 5.5))
    x = np.arange(len(cases))
    markers = "os^vD<>ph*"
    for i, m in enumerate(methods):
        y = [ratios[c].get(m, math.nan) for c in cases]
        ax.plot(x + (i - (len(methods) - 1) / 2) * 0.08, y, markers[i % len(markers)], label=m,
                markersize=7 if m == REFERENCE_METHOD else 5, zorder=3 if m == REFERENCE_METHOD else 2)
    ax.axhline(1.0, color="grey", linewidth=1)
    ax.set_yscale("log")
    ax.set_xticks(x)
    ax.set_xticklabels(cases, rotation=60, ha="right", fontsize=8)
    ax.set_ylabel("rotation RMSE / best other method's")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", axis="y", alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--manifest", required=True, help="case<TAB>seed<TAB>csv<TAB>log<TAB>description per line")
    parser.add_argument("--out", required=True)
    parser.add_argument("--machine", default="")
    parser.add_argument("--date", default="")
    parser.add_argument("--note", action="append", default=[], help="a line for the head of score.md")
    args = parser.parse_args()

    bound = chi_square_bound()
    runs = defaultdict(lambda: defaultdict(list))  # case -> method -> [run per seed]
    debias, notes, cases, seeds = {}, {}, [], []
    with open(args.manifest) as f:
        for line in f:
            if not line.strip():
                continue
            case, seed, path, log, description = line.rstrip("\n").split("\t")
            if not os.path.isfile(path):
                print(f"[score] {case} seed {seed}: no CSV ({path}); left out", file=sys.stderr)
                continue
            if case not in notes:
                cases.append(case)
                truth = read_truth(log)
                debias[case] = truth == "gyro"
                notes[case] = description + (f"; truth: {truth}" if truth else "") + \
                    ("; the gyro's constant bias removed (per-axis mean error of each run)" if debias[case] else "")
            if seed not in seeds:
                seeds.append(seed)
            for method, run in read_frames(path).items():
                runs[case][method].append((seed, run))
    if not cases:
        sys.exit("[score] no results")
    methods = sorted({m for c in cases for m in runs[c]}, key=lambda m: (m != REFERENCE_METHOD, is_ablation(m), m))
    per_case = {c: {m: summarise(runs[c][m], debias[c], bound) for m in runs[c]} for c in cases}
    ratios = {c: ratios_to_best_peer({m: f["rmse"] for m, f in per_case[c].items()}) for c in cases}
    per_method = {m: over_cases({c: ratios[c].get(m, math.nan) for c in cases}) for m in methods}
    spread = seed_spread(per_case, seeds)
    ablation = ablation_rows(methods, per_case, per_method, spread)

    os.makedirs(args.out, exist_ok=True)
    header = [f"Machine: {args.machine}. Date: {args.date}.", f"{len(cases)} cases, methods {', '.join(methods)}, "
              f"estimator seeds {', '.join(seeds)} pooled.", *args.note]
    write_markdown(os.path.join(args.out, "score.md"), header, cases, methods, per_case, ratios, per_method, spread, notes,
                   ablation)
    write_csv(os.path.join(args.out, "score.csv"), cases, methods, per_case, ratios)
    write_plot(os.path.join(args.out, "score.png"), cases, [m for m in methods if not is_ablation(m)], ratios,
               f"make score: {len(cases)} cases, seeds {','.join(seeds)} ({args.machine}, {args.date})")
    vote = per_method.get(REFERENCE_METHOD, {"geomean": math.nan, "worst": math.nan, "worst_case": ""})
    clean = lambda v: None if isinstance(v, float) and not math.isfinite(v) else (round(v, 4) if isinstance(v, float) else v)
    summary = {
        "cases": len(cases),
        "vote_vs_best_peer": {k: clean(v) for k, v in vote.items()},
        "per_method": {m: {k: clean(v) for k, v in s.items()} for m, s in per_method.items() if not is_ablation(m)},
        "seed_spread": {"seeds": spread["seeds"], "relative": clean(spread["relative"]),
                        "geomean_per_seed": [clean(g) for g in spread["geomean_per_seed"]],
                        "per_case_rmse_geomean": clean(spread["per_case_rmse_geomean"])},
    }
    clean_all = lambda v: {k: clean_all(x) for k, x in v.items()} if isinstance(v, dict) else clean(v)
    summary["goals"] = clean_all(goals(per_case, ratios, per_method))
    if ablation:
        summary["ablation"] = {r["part"]: {"geomean": clean(r["geomean"]), "worst": clean(r["worst"]),
                                           "vs_vote_geomean": clean(r["vs_vote"]["geomean"]),
                                           "nees_mean": clean(r["nees_mean"]),
                                           "overconfident_cases": len(r["overconfident"]), "verdict": r["verdict"]}
                               for r in ablation}
    line = json.dumps(summary)
    with open(os.path.join(args.out, "score.json"), "w") as f:
        f.write(line + "\n")
    print(line)


if __name__ == "__main__":
    main()
