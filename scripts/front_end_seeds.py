#!/usr/bin/env python3
"""Native front end against KLT over estimator seeds (part of `make bench`).

One run of `evaluate` draws its hypotheses from one seed, and on a hand-held sequence a few frames
whose pan is poorly determined (the rotation/translation valley of near structure) can move a
sequence's RMSE by a tenth either way. So each front end is evaluated with seeds 1..N and compared
frame by frame: the mean RMSE over the seeds, and the paired statistic of the per-frame squared
errors (native minus KLT), mean / standard error, averaged over the seeds. |z| below 2 is no
measurable difference.

Usage: front_end_seeds.py --evaluate BIN --out FILE.md [--seeds N] NAME=FOLDER ...
"""
import argparse
import csv
import math
import os
import subprocess
import sys
import tempfile

CONFIGS = [
    ("native, integer positions", ["--set", "subpixel_refinement=false", "--set", "track_unmatched=false"]),
    ("native, sub-pixel positions", ["--set", "subpixel_refinement=true", "--set", "track_unmatched=false"]),
    ("native, sub-pixel positions and tracking (defaults)",
     ["--set", "subpixel_refinement=true", "--set", "track_unmatched=true"]),
    ("klt", ["--front-end", "klt"]),
]
REFERENCE = "klt"


def frame_errors(evaluate, folder, options, seed, scratch):
    """vote's rotation error [deg] per frame, from evaluate's per-frame CSV."""
    path = os.path.join(scratch, "frames.csv")
    command = [evaluate, folder, "--method", "vote", "--quiet", "--set", f"seed={seed}", "--csv", path] + options
    result = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if result.returncode != 0:
        sys.exit(f"[front_end_seeds] {' '.join(command)} failed:\n{result.stdout[-2000:]}")
    with open(path, newline="") as f:
        return {int(row["frame"]): float(row["rot_err_deg"]) for row in csv.DictReader(f)
                if row["method"] == "vote" and row["rot_err_deg"] not in ("", "nan")}


def rmse(values):
    return math.sqrt(sum(v * v for v in values) / len(values))


def paired_z(errors, reference):
    frames = sorted(set(errors) & set(reference))
    d = [errors[f] ** 2 - reference[f] ** 2 for f in frames]
    mean = sum(d) / len(d)
    sd = math.sqrt(sum((x - mean) ** 2 for x in d) / (len(d) - 1))
    return mean / (sd / math.sqrt(len(d))) if sd > 0 else 0.0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--evaluate", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--seeds", type=int, default=6)
    parser.add_argument("sequences", nargs="+", help="NAME=FOLDER")
    args = parser.parse_args()

    lines = [f"vote's rotation RMSE [deg] over estimator seeds 1..{args.seeds} (mean, min-max), and the paired "
             "per-frame z against KLT (mean over the seeds; |z| < 2: no measurable difference):", "",
             "| sequence | front end | RMSE mean | RMSE min-max | z against KLT |", "|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as scratch:
        for item in args.sequences:
            name, folder = item.split("=", 1)
            runs = {label: [frame_errors(args.evaluate, folder, options, seed, scratch)
                            for seed in range(1, args.seeds + 1)] for label, options in CONFIGS}
            for label, _ in CONFIGS:
                rmses = [rmse(list(e.values())) for e in runs[label]]
                z = "" if label == REFERENCE else "%.1f" % (
                    sum(paired_z(e, r) for e, r in zip(runs[label], runs[REFERENCE])) / args.seeds)
                lines.append(f"| {name} | {label} | {sum(rmses) / len(rmses):.4f} | "
                             f"{min(rmses):.4f}-{max(rmses):.4f} | {z} |")
            print(f"[front_end_seeds] {name} done", flush=True)
    with open(args.out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
