#!/usr/bin/env python3
"""vote on the shaken drone at growing frame strides, over estimator seeds (part of `make bench`).

With pairs several frames apart near structure a frame's basin along the rotation/translation
valley can depend on which random triples were drawn, so one seed's RMSE and NEES there are one
draw among many: the bench's single-seed rows of the strides are read beside this spread. Each
stride is evaluated with seeds 1..N (the estimator's draws change, and through the estimates that
guide the next pair's matching, a few matches too) and the table gives the mean and the range of
the RMSE, the worst frame, the NEES mean and the share of frames beyond the 99 % bound.

Usage: motion_seeds.py --evaluate BIN --out FILE.md [--seeds N] [--strides 1,2,3,4] FOLDER
"""
import argparse
import json
import subprocess
import sys

FIGURES = [("rot_rmse_deg", "RMSE [°]", 4), ("rot_max_deg", "worst frame [°]", 3),
           ("nees_mean", "NEES mean", 2), ("nees_beyond_99", "beyond 99 %", 2)]


def summary(evaluate, folder, stride, seed):
    """evaluate's JSON summary of vote at one stride and seed."""
    command = [evaluate, folder, "--method", "vote", "--quiet", "--backend", "cpu", "--stride", str(stride),
               "--seed", str(seed)]
    result = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = [line for line in result.stdout.splitlines() if line.startswith("{")]
    if result.returncode != 0 or not lines:
        sys.exit(f"[motion_seeds] {' '.join(command)} failed:\n{result.stdout[-2000:]}")
    return json.loads(lines[-1])


def cell(values, digits):
    """mean (min-max) of the seeds' values; n/a without any."""
    values = [v for v in values if v is not None]
    if not values:
        return "n/a"
    return f"{sum(values) / len(values):.{digits}f} ({min(values):.{digits}f}-{max(values):.{digits}f})"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--evaluate", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--seeds", type=int, default=6)
    parser.add_argument("--strides", default="1,2,3,4")
    parser.add_argument("folder")
    args = parser.parse_args()
    if args.seeds < 1:
        sys.exit("[motion_seeds] --seeds must be at least 1")
    strides = [int(s) for s in args.strides.split(",") if s]
    out = [f"vote on {args.folder.rstrip('/').split('/')[-1]} at frame strides {args.strides}, estimator seeds "
           f"1..{args.seeds} (mean (min-max) over the seeds):", "",
           "| stride | " + " | ".join(name for _, name, _ in FIGURES) + " |",
           "|---" * (len(FIGURES) + 1) + "|"]
    for stride in strides:
        runs = [summary(args.evaluate, args.folder, stride, seed) for seed in range(1, args.seeds + 1)]
        out.append(f"| {stride} | " + " | ".join(cell([r.get(key) for r in runs], digits)
                                                  for key, _, digits in FIGURES) + " |")
    with open(args.out, "w") as f:
        f.write("\n".join(out) + "\n")
    print("\n".join(out))


if __name__ == "__main__":
    main()
