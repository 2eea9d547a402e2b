#!/usr/bin/python3
"""Turns the benchmark's JSON lines (one per method and run of `evaluate`) into out/bench/
results.csv, table.md and PNG plots. Run by scripts/bench.sh with Debian's python3
(python3-matplotlib, python3-numpy).

Inputs:
  --results  results.jsonl: evaluate's JSON objects plus group (shared, rendered, outliers,
             outliers_near, translation, motion, textures, front_end), label and x (outlier
             fraction, frame stride or texture seed) added by bench.sh
  --sweep    CSVs of `evaluate --timing-sweep` (series, method, backend, hypotheses, matches,
             real_fraction, ms_mean, ...), one per backend
  --gpu-dir  folder of CSVs from the GPU stand-alone bench; any with a `hypotheses` column and a
             time column (ms_mean, ms, time_ms or kernel_ms) joins the timing plots
"""
import argparse
import csv
import glob
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

# The front end's stages as evaluate times them (ms_per_frame): everything before the estimate.
FRONT_END_STAGES = ("detect", "describe", "match", "align")
# The stages of the guided-against-global time goal: detection, description and descriptor
# matching, without the sub-pixel alignment that both modes run alike.
MATCHING_GOAL_STAGES = ("detect", "describe", "match")

METHOD_ORDER = ["vote", "paper", "essential5", "fundamental8", "opengv_rotation_only",
                "opengv_eigensolver", "opengv_5pt"]
CSV_FIELDS = ["group", "label", "x", "dataset", "method", "front_end", "matching", "backend", "frames", "invalid",
              "rot_rmse_deg", "rot_max_deg", "yaw_rmse_deg", "yaw_max_deg", "mean_rate_dps",
              "rate_rmse_dps", "ms_detect", "ms_describe", "ms_match", "ms_align", "ms_estimate", "ms_total",
              "matches_mean", "tracked_mean", "outliers", "stride", "true_rot_mean_deg", "true_trans_mean_m", "truth",
              "nees_mean", "nees_beyond_99"]


def method_key(m):
    return (METHOD_ORDER.index(m) if m in METHOD_ORDER else len(METHOD_ORDER), m)


def num(v):
    return float("nan") if v is None else float(v)


def fmt(v, digits=3):
    v = num(v)
    return "n/a" if math.isnan(v) else f"{v:.{digits}f}"


def load_results(path):
    rows = []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            r = json.loads(line)
            ms = r.get("ms_per_frame") or {}
            for k in FRONT_END_STAGES + ("estimate", "total"):
                r["ms_" + k] = ms.get(k)
            rows.append(r)
    return rows


def write_csv(rows, path):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in CSV_FIELDS})


def runs_of(rows):
    """Runs (group, label) in first-seen order, each with {method: row}."""
    runs = {}
    for r in rows:
        runs.setdefault((r["group"], r["label"]), {})[r["method"]] = r
    return runs


def method_table(runs, methods, cell):
    """Markdown rows: one per run, one column per method, cell(row) where the method ran, else '-'."""
    out = ["| sequence | " + " | ".join(methods) + " |", "|---" * (len(methods) + 1) + "|"]
    for (_, label), by_method in runs.items():
        cells = [cell(by_method[m]) if m in by_method else "-" for m in methods]
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    return out


FRONT_END_VARIANTS = [("guided", "native, guided matching, sub-pixel positions, tracking (defaults)"),
                      ("subpixel", "native, guided matching, sub-pixel positions, no tracking"),
                      ("integer", "native, guided matching, integer positions, no tracking"),
                      ("global", "native, global matching"),
                      ("fixed_global", "fixed FAST threshold, global matching (before)"),
                      ("orb", "OpenCV ORB + brute force"), ("klt", "goodFeaturesToTrack + pyramidal LK")]


def front_end_table(rows):
    """Markdown: per sequence, vote on each front end's matches (group front_end, label
    '<sequence>:<variant>'), then the goal ratios measured in the same run."""
    by_seq = {}
    for r in rows:
        if r.get("group") != "front_end" or r.get("method") != "vote":
            continue
        seq, _, variant = r["label"].partition(":")
        by_seq.setdefault(seq, {})[variant] = r
    if not by_seq:
        return []
    out = ["\n## Front ends on the same frames (vote) [ms per frame; deg]\n",
           "front end = detect + describe + match + align (sub-pixel refinement and tracking); total = "
           "front end + estimate. Guided pairs: pairs matched around the prior's prediction (the others: "
           "first pair, or fell back to global).\n",
           "| sequence | front end | matches | detect | describe | match | align | front end | estimate | total | "
           "rot RMSE / max | guided (fallbacks) |",
           "|---" * 12 + "|"]

    def fe_ms(r, stages=FRONT_END_STAGES):
        return sum(num(r.get("ms_" + k)) for k in stages)

    goals = []
    for seq, variants in by_seq.items():
        for key, name in FRONT_END_VARIANTS:
            r = variants.get(key)
            if r is None:
                continue
            guided = (f"{r.get('guided_pairs', 0)} ({r.get('fallback_pairs', 0)})"
                      if r.get("matching") == "guided" else "-")
            matches = fmt(r.get('matches_mean'), 0)
            if num(r.get("tracked_mean", 0)) > 0:
                matches += f" ({fmt(r.get('tracked_mean'), 0)} tracked)"
            out.append(f"| {seq} | {name} | {matches} | {fmt(r.get('ms_detect'), 2)} | "
                       f"{fmt(r.get('ms_describe'), 2)} | {fmt(r.get('ms_match'), 2)} | {fmt(r.get('ms_align'), 2)} | "
                       f"{fmt(fe_ms(r), 2)} | "
                       f"{fmt(r.get('ms_estimate'), 2)} | {fmt(r.get('ms_total'), 2)} | "
                       f"{fmt(r['rot_rmse_deg'])} / {fmt(r['rot_max_deg'])} | {guided} |")
        g = variants.get("guided")
        if g is None:
            continue
        parts = []
        if "global" in variants:
            glob_row = variants["global"]
            parts.append("guided / global time: match "
                         f"{fmt(fe_ms(g, ('match',)) / fe_ms(glob_row, ('match',)), 2)}, "
                         "detect + describe + match "
                         f"{fmt(fe_ms(g, MATCHING_GOAL_STAGES) / fe_ms(glob_row, MATCHING_GOAL_STAGES), 2)}, "
                         f"whole front end {fmt(fe_ms(g) / fe_ms(glob_row), 2)}")
        for other in ("orb", "klt"):
            if other in variants:
                parts.append(f"{other} / native front-end time {fmt(fe_ms(variants[other]) / fe_ms(g), 1)}")
        if "fixed_global" in variants:
            parts.append(f"matches {fmt(g.get('matches_mean'), 0)} (before: "
                         f"{fmt(variants['fixed_global'].get('matches_mean'), 0)})")
        whole = f"; whole pipeline {fmt(num(g.get('ms_total')), 2)} ms"
        others = [f"{fmt(num(variants[key].get('ms_total')), 2)} ms {what}"
                  for key, what in (("subpixel", "without tracking"),
                                    ("integer", "with integer positions and no tracking"))
                  if key in variants]
        if others:
            whole += " (" + ", ".join(others) + ")"
        goals.append(f"- {seq}: " + "; ".join(parts) + whole)
    return out + ["", "Measured ratios (same run):\n"] + goals


def write_table(rows, methods, path, machine, sweep_rows):
    fe_rows = front_end_table(rows)
    rows = [r for r in rows if r.get("group") != "front_end"]
    runs = runs_of(rows)
    out = []
    out.append("# visual_gyro benchmark\n")
    out.append(f"Machine: {machine}. Same matches for every method within a row; invalid estimates "
               "count as identity rotation. Rotation error = angle of R_est^-1 R_true per frame "
               "pair; yaw about the camera's vertical axis.\n")
    for (group, label), by_method in runs.items():
        first = next(iter(by_method.values()))
        gyro = first.get("gyro_mean_rate_dps")
        bias = first.get("gyro_bias_rad_s")
        if gyro is not None and first.get("truth", "gyro") == "gyro" and first.get("gyro_aligned") and bias:
            offset = first.get("time_offset_ms")
            offset_text = f"{float(offset):.2f} ms" if offset is not None else "not observable, 0"
            out.append(f"{label}: the reference is the gyro aligned with the first method's estimates (bias "
                       f"{bias[0]:.4f} {bias[1]:.4f} {bias[2]:.4f} rad/s removed, clock offset {offset_text}).\n")
        elif gyro is not None and first.get("truth", "gyro") == "gyro":
            out.append(f"{label}: the reference is the raw gyro as the loader integrates it (bias not removed; "
                       f"it reads {float(gyro):.2f} deg/s on average), so its rotation errors mostly measure that "
                       "bias; the mean estimated rate is the telling figure there.\n")
    def rot_cell(r):
        cell = f"{fmt(r['rot_rmse_deg'])} / {fmt(r['rot_max_deg'])}"
        return cell + (f" ({r['invalid']} inv.)" if r.get("invalid") else "")

    def yaw_cell(r):
        cell = f"{fmt(r['yaw_rmse_deg'])}; {fmt(r['mean_rate_dps'])}"
        return cell + (f" ({fmt(r['rate_rmse_dps'])})" if r.get("rate_rmse_dps") is not None else "")

    out.append("## Rotation error RMSE / max per frame pair [deg]\n")
    out.extend(method_table(runs, methods, rot_cell))
    out.append("\n## Yaw error RMSE [deg]; mean estimated rate [deg/s] (rate RMSE vs the reference rate -- gyro or EuRoC poses -- where one exists)\n")
    out.extend(method_table(runs, methods, yaw_cell))
    nees_methods = [m for m in methods if any(r.get("nees_mean") is not None for r in rows if r["method"] == m)]
    if nees_methods:
        out.append("\n## Covariance: NEES mean (3 when honest); frames beyond the 99 % chi-square bound\n")
        out.append("Normalised estimation error squared of the rotation vector, e^T C^-1 e, over the valid frames "
                   "of sequences whose truth is poses (a gyro's bias is no estimation error). Goal: mean in "
                   "[1, 6], at most 5 % of frames beyond 11.34.\n")
        out.extend(method_table({k: v for k, v in runs.items()
                                 if any(r.get("nees_mean") is not None for r in v.values())},
                                nees_methods,
                                lambda r: (f"{fmt(r.get('nees_mean'), 2)}; {100 * num(r.get('nees_beyond_99')):.1f} %"
                                           if r.get("nees_mean") is not None else "n/a")))
    out.append("\n## Estimation time per frame pair [ms] (front end shared: detect + describe + match + align)\n")
    out.append("| sequence | matches | front end | " + " | ".join(methods) + " |")
    out.append("|---" * (len(methods) + 3) + "|")
    for (group, label), by_method in runs.items():
        any_row = next(iter(by_method.values()))
        front = sum(num(any_row.get("ms_" + k)) for k in FRONT_END_STAGES)
        cells = [fmt(by_method[m]["ms_estimate"], 2) if m in by_method else "-" for m in methods]
        out.append(f"| {label} | {fmt(any_row.get('matches_mean'), 0)} | {fmt(front, 1)} | "
                   + " | ".join(cells) + " |")
    out.extend(fe_rows)
    if sweep_rows:
        out.extend(sweep_tables(sweep_rows))
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def fmt_cell(v):
    """A sweep table cell: '-' where the method has no such point."""
    return "-" if math.isnan(v) else f"{v:.3f}"


def sweep_keys(rows):
    """(method, backend) pairs of sweep rows, vote/paper first, CPU before CUDA."""
    return sorted({(r["method"], r["backend"]) for r in rows}, key=lambda k: (method_key(k[0]), k[1]))


def sweep_point(rows, series, method, backend, x_key, x):
    hit = [r for r in rows if r["series"] == series and r["method"] == method and r["backend"] == backend
           and int(r[x_key]) == x]
    return float(hit[0]["ms_mean"]) if hit else float("nan")


def sweep_tables(rows):
    """Markdown tables of `evaluate --timing-sweep` rows (series hypotheses and matches), with the
    CUDA speed-up over the CPU where both backends ran."""
    out = []
    dataset = rows[0].get("dataset", "")
    hyp_rows = [r for r in rows if r["series"] == "hypotheses"]
    match_rows = [r for r in rows if r["series"] == "matches"]
    if hyp_rows:
        at = int(hyp_rows[0]["matches"])
        hyps = sorted({int(r["hypotheses"]) for r in hyp_rows if int(r["hypotheses"]) > 0})
        out.append(f"\n## Estimation time vs hypotheses [ms] ({dataset}, {at} matches; methods without a "
                   "hypothesis count run their own adaptive RANSAC once)\n")
        out.append("| method | backend | " + " | ".join(str(h) for h in hyps) + " | adaptive |")
        out.append("|---" * (len(hyps) + 3) + "|")
        for method, backend in sweep_keys(hyp_rows):
            cells = [fmt_cell(sweep_point(hyp_rows, "hypotheses", method, backend, "hypotheses", h)) for h in hyps]
            own = fmt_cell(sweep_point(hyp_rows, "hypotheses", method, backend, "hypotheses", 0))
            out.append(f"| {method} | {backend} | " + " | ".join(cells) + f" | {own} |")
        out.extend(split_rows(hyp_rows, "hypotheses", hyps, extra_cells=1))
        out.extend(speedup_rows(hyp_rows, "hypotheses", "hypotheses", hyps, extra_cells=1))
    if match_rows:
        at = max(int(r["hypotheses"]) for r in match_rows)
        ms = sorted({int(r["matches"]) for r in match_rows})
        real = {int(r["matches"]): float(r.get("real_fraction") or 1.0) for r in match_rows}
        out.append(f"\n## Estimation time vs matches [ms] ({dataset}; vote/paper at {at} hypotheses)\n")
        out.append("| method | backend | " + " | ".join(str(m) for m in ms) + " |")
        out.append("|---" * (len(ms) + 2) + "|")
        out.append("| (real matches) | | " + " | ".join(f"{100 * real[m]:.0f} %" for m in ms) + " |")
        for method, backend in sweep_keys(match_rows):
            cells = [fmt_cell(sweep_point(match_rows, "matches", method, backend, "matches", m)) for m in ms]
            out.append(f"| {method} | {backend} | " + " | ".join(cells) + " |")
        out.extend(split_rows(match_rows, "matches", ms))
        out.extend(speedup_rows(match_rows, "matches", "matches", ms))
        if any(v < 1.0 for v in real.values()):
            out.append("\nWhere fewer than 100 % of the matches are real, the pairs were topped up with "
                       "copies of their own matches, each bearing jittered by half a pixel.")
    return out


def split_rows(rows, x_key, xs, extra_cells=0):
    """For vote/paper: the estimate split into the voter call and the host part after it
    (winner read-out, verification, refinement), 'voter / host' in ms."""
    out = []
    for method, backend in sweep_keys(rows):
        sel = [r for r in rows if r["method"] == method and r["backend"] == backend and r.get("vote_ms_mean")]
        if not sel:
            continue
        cells = []
        for x in xs:
            hit = [r for r in sel if int(r[x_key]) == x]
            cells.append(f"{float(hit[0]['vote_ms_mean']):.2f} / {float(hit[0]['refine_ms_mean']):.2f}"
                         if hit else "-")
        out.append(f"| {method}: voter / host part | {backend} | " + " | ".join(cells + ["-"] * extra_cells) + " |")
    return out


def speedup_rows(rows, series, x_key, xs, extra_cells=0):
    """CPU time / CUDA time per method and x, when both backends ran."""
    out = []
    for method in sorted({r["method"] for r in rows if r["backend"] == "cuda"}, key=method_key):
        cells = []
        for x in xs:
            cpu = sweep_point(rows, series, method, "cpu", x_key, x)
            gpu = sweep_point(rows, series, method, "cuda", x_key, x)
            cells.append(f"{cpu / gpu:.1f}x" if cpu == cpu and gpu == gpu and gpu > 0 else "-")
        out.append(f"| {method} speed-up | cuda vs cpu | " + " | ".join(cells + ["-"] * extra_cells) + " |")
    return out


def bar_plot(rows, methods, key, ylabel, title, path, log=True, groups=("shared", "rendered")):
    runs = [(k, v) for k, v in runs_of(rows).items() if k[0] in groups]
    if not runs:
        return
    fig, ax = plt.subplots(figsize=(max(8, 1.6 * len(runs) + 5), 4.5))
    width = 0.8 / max(1, len(methods))
    x = np.arange(len(runs))
    for i, m in enumerate(methods):
        vals = [num(v.get(m, {}).get(key)) for _, v in runs]
        vals = [max(v, 1e-4) if not math.isnan(v) else np.nan for v in vals]
        ax.bar(x + (i - (len(methods) - 1) / 2) * width, vals, width, label=m)
    ax.set_xticks(x)
    ax.set_xticklabels([k[1] for k, _ in runs], rotation=15)
    if log:
        ax.set_yscale("log")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(axis="y", alpha=0.3, which="both")
    ax.legend(fontsize=8, bbox_to_anchor=(1.01, 1.0), loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def line_plot(rows, methods, group, xlabel, path, title, xkey="x"):
    sel = [r for r in rows if r["group"] == group or (r["group"] == "rendered" and r["label"] == base_of(group))]
    if len({r["label"] for r in sel}) < 2:
        return
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for m in methods:
        # The unmodified rendered run is the first point (no outliers: x = 0; stride 1).
        pts = sorted((num(r.get(xkey)), num(r["rot_rmse_deg"]), num(r["yaw_rmse_deg"]))
                     for r in sel if r["method"] == m and not math.isnan(num(r.get(xkey))))
        if not pts:
            continue
        xs, rot, yaw = zip(*pts)
        axes[0].plot(xs, rot, marker="o", label=m)
        axes[1].plot(xs, yaw, marker="o", label=m)
    for ax, what in zip(axes, ("rotation error RMSE [deg]", "yaw error RMSE [deg]")):
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(what)
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def nees_plot(rows, methods, path):
    """NEES mean per sequence (pose truth) for the methods that give a covariance, with the
    honest value 3 and the goal band [1, 6] marked."""
    with_nees = [r for r in rows if r.get("nees_mean") is not None and r["group"] in ("shared", "rendered")]
    if not with_nees:
        return
    labels = list(dict.fromkeys(r["label"] for r in with_nees))
    ms = [m for m in methods if any(r["method"] == m for r in with_nees)]
    fig, ax = plt.subplots(figsize=(max(7, 1.4 * len(labels) + 4), 4.2))
    width = 0.8 / max(1, len(ms))
    x = np.arange(len(labels))
    for i, m in enumerate(ms):
        vals = [next((num(r["nees_mean"]) for r in with_nees if r["label"] == lab and r["method"] == m), np.nan)
                for lab in labels]
        ax.bar(x + (i - (len(ms) - 1) / 2) * width, vals, width, label=m)
    ax.axhspan(1.0, 6.0, color="green", alpha=0.08, label="goal [1, 6]")
    ax.axhline(3.0, color="green", lw=1, label="honest: 3")
    ax.set_yscale("log")
    ax.set_xticks(x)
    ax.set_xticklabels(labels, rotation=15)
    ax.set_ylabel("NEES mean (rotation vector)")
    ax.set_title("covariance honesty per sequence")
    ax.grid(axis="y", alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def base_of(group):
    return {"outliers": "drive", "translation": "forward"}.get(group, "")


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def load_gpu(gpu_dir):
    """Timing rows of the GPU stand-alone bench (scripts/gpu_bench.sh -> out/gpu/bench_*.csv:
    series, grid, backend, matches, hypotheses, call_ms_median, ...). Other CSVs there (checks)
    lack a hypotheses or time column and are skipped."""
    rows = []
    for path in sorted(glob.glob(os.path.join(gpu_dir, "*.csv"))):
        try:
            data = read_csv(path)
        except (OSError, csv.Error, UnicodeDecodeError) as e:
            print(f"[bench_plot] skipping {path}: {e}", file=sys.stderr)
            continue
        if not data or "hypotheses" not in data[0]:
            continue
        tkey = next((k for k in ("call_ms_median", "ms_mean", "ms_median", "ms", "time_ms") if k in data[0]), None)
        if tkey is None:
            continue
        name = os.path.splitext(os.path.basename(path))[0]
        for d in data:
            try:
                grid = d.get("grid") or ""
                rows.append({"method": d.get("method") or (f"{grid} voter" if grid else "voter"),
                             "backend": d.get("backend") or "cuda",
                             "hypotheses": int(float(d["hypotheses"])),
                             "matches": int(float(d.get("matches") or 0)),
                             "series": d.get("series") or "",
                             "ms_mean": float(d[tkey]), "source": name})
            except (TypeError, ValueError, KeyError):
                continue
    return rows


def timing_plots(sweep_rows, gpu_rows, out):
    """Left: time vs hypotheses; right: time vs matches. Sweep rows (solid) are whole estimators on
    real matches (per backend; baselines without a hypothesis count as horizontal lines on the
    left); GPU-bench rows (dashed) time the hypothesis voter alone (CPU gold and CUDA)."""
    if not sweep_rows and not gpu_rows:
        return
    fig, axes = plt.subplots(1, 2, figsize=(13, 5))

    def curve(ax, pts, label, style):
        pts = sorted(pts)
        if len(pts) < 2:
            return None
        xs, ys = zip(*pts)
        return ax.plot(xs, ys, style, marker="o", label=label)[0]

    # Time vs hypotheses.
    ax = axes[0]
    hyp_rows = [r for r in sweep_rows if r["series"] == "hypotheses"]
    at_matches = int(hyp_rows[0]["matches"]) if hyp_rows else 0
    for method, backend in sweep_keys(hyp_rows):
        own = [r for r in hyp_rows if r["method"] == method and r["backend"] == backend]
        pts = [(int(r["hypotheses"]), float(r["ms_mean"])) for r in own if int(r["hypotheses"]) > 0]
        if pts:
            curve(ax, pts, f"{method} ({backend})", "-")
        else:
            ax.axhline(float(own[0]["ms_mean"]), linestyle=":", color=f"C{method_key(method)[0] % 10}",
                       label=f"{method} ({backend}, adaptive RANSAC)")
    for key in sorted({(r["method"], r["backend"], r["source"]) for r in gpu_rows if r["series"] in ("", "hypotheses")}):
        sel = [r for r in gpu_rows if (r["method"], r["backend"], r["source"]) == key and r["series"] in ("", "hypotheses")]
        n = max(int(r["matches"]) for r in sel)
        pts = [(int(r["hypotheses"]), float(r["ms_mean"])) for r in sel if int(r["matches"]) == n]
        curve(ax, pts, f"{key[0]} ({key[1]}, {n} matches) [{key[2]}]", "--")
    ax.set_xlabel("hypotheses per frame")
    ax.set_title(f"estimation time vs hypotheses ({at_matches} matches)")

    # Time vs matches.
    ax = axes[1]
    match_rows = [r for r in sweep_rows if r["series"] == "matches"]
    at_hyps = max((int(r["hypotheses"]) for r in match_rows), default=0)
    for method, backend in sweep_keys(match_rows):
        pts = [(int(r["matches"]), float(r["ms_mean"])) for r in match_rows
               if r["method"] == method and r["backend"] == backend]
        curve(ax, pts, f"{method} ({backend})", "-")
    topped = sorted(int(r["matches"]) for r in match_rows if float(r.get("real_fraction") or 1.0) < 1.0)
    if topped:
        ax.axvspan(topped[0] / 1.2, topped[-1] * 1.2, color="0.9", zorder=0,
                   label="pairs topped up with jittered copies")
    for key in sorted({(r["method"], r["backend"], r["source"]) for r in gpu_rows if r["series"] in ("", "matches")}):
        sel = [r for r in gpu_rows if (r["method"], r["backend"], r["source"]) == key and r["series"] in ("", "matches")]
        h = max(int(r["hypotheses"]) for r in sel)
        pts = [(int(r["matches"]), float(r["ms_mean"])) for r in sel if int(r["hypotheses"]) == h]
        curve(ax, pts, f"{key[0]} ({key[1]}, {h} hyp.) [{key[2]}]", "--")
    ax.set_xlabel("matches per frame pair")
    ax.set_title(f"estimation time vs matches (vote/paper: {at_hyps} hypotheses)")
    for ax in axes:
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylabel("time per frame [ms]")
        ax.grid(alpha=0.3, which="both")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "timing_sweep.png"), dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--results", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--sweep", nargs="*", default=[], help="CSVs of evaluate --timing-sweep (one per backend)")
    ap.add_argument("--gpu-dir", default="")
    ap.add_argument("--machine", default="unknown machine")
    a = ap.parse_args()

    rows = load_results(a.results) if os.path.exists(a.results) else []
    if not rows:
        print("[bench_plot] no results to tabulate", file=sys.stderr)
        return 1
    methods = sorted({r["method"] for r in rows}, key=method_key)
    sweep_rows = [r for path in a.sweep if os.path.exists(path) for r in read_csv(path)]
    gpu_rows = load_gpu(a.gpu_dir) if a.gpu_dir and os.path.isdir(a.gpu_dir) else []

    write_csv(rows, os.path.join(a.out, "results.csv"))
    write_table(rows, methods, os.path.join(a.out, "table.md"), a.machine, sweep_rows)
    rows = [r for r in rows if r.get("group") != "front_end"]  # their own table only
    bar_plot(rows, methods, "rot_rmse_deg", "rotation error RMSE [deg]",
             "accuracy per method and sequence", os.path.join(a.out, "accuracy.png"))
    bar_plot(rows, methods, "yaw_rmse_deg", "yaw error RMSE [deg]",
             "yaw accuracy per method and sequence", os.path.join(a.out, "accuracy_yaw.png"))
    nees_plot(rows, methods, os.path.join(a.out, "nees.png"))
    bar_plot(rows, methods, "ms_estimate", "estimate time per frame pair [ms]",
             f"estimation time ({a.machine})", os.path.join(a.out, "estimate_time.png"))
    line_plot(rows, methods, "outliers", "injected outlier fraction", os.path.join(a.out, "accuracy_vs_outliers.png"),
              "rendered drive: accuracy vs outlier ratio")
    line_plot(rows, methods, "translation", "true translation per frame pair [m] (frame stride 1, 2, 3, 4)",
              os.path.join(a.out, "accuracy_vs_translation.png"), "rendered forward drive: accuracy vs translation",
              xkey="true_trans_mean_m")
    timing_plots(sweep_rows, gpu_rows, a.out)
    pngs = sorted(os.path.basename(p) for p in glob.glob(os.path.join(a.out, "*.png")))
    print(f"[bench_plot] wrote results.csv, table.md, {', '.join(pngs)}" +
          (f" (GPU CSV rows: {len(gpu_rows)})" if gpu_rows else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
