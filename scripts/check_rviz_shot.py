#!/usr/bin/python3
"""Checks a screenshot of rviz with config/visual_gyro.rviz (scripts/rviz_shot.sh):
- the 3D view is found as the block of the background colour (48, 48, 48);
- inside it, the yaw plot's estimate colour and ground-truth colour each cover at least
  --min-pixels pixels (colours as src/ros/yaw_plot.cpp draws them);
- left of it (the Displays panel and the image, without the icon column), no pixel has rviz's
  warning or error status colour.
Prints one line per finding and exits 1 when a check fails.

Usage: check_rviz_shot.py SCREENSHOT.png [--min-pixels N]"""
import argparse
import sys

import numpy as np
from PIL import Image

BACKGROUND = (48, 48, 48)            # config/visual_gyro.rviz Background Color
ESTIMATE = (25, 229, 25)             # yaw_plot.cpp kEstimateColour (0.1, 0.9, 0.1)
GROUND_TRUTH = (229, 51, 25)         # yaw_plot.cpp kTruthColour (0.9, 0.2, 0.1)
# rviz draws a display's name and status text in orange (192, 128, 0) for Warn and in red for
# Error; any strongly orange or red pixel of the panel counts (OK text is black or blue).
PANEL_COLOURS = (
    ("warning (orange)", lambda p: (p[..., 0] >= 150) & (p[..., 1] >= 90) & (p[..., 1] <= 170) & (p[..., 2] <= 60)),
    ("error (red)", lambda p: (p[..., 0] >= 150) & (p[..., 1] <= 100) & (p[..., 2] <= 100)),
)
TOLERANCE = 30                       # colour distance still counted as the colour
# The Displays tree draws each top-level display's icon (the Marker icon has a red ball) in the
# screen's first 40 pixel columns; names and status texts, which take the status colour, start
# right of them.
ICON_COLUMNS = 40


def count_near(pixels, colour):
    distance = np.sqrt(((pixels - np.array(colour)) ** 2).sum(axis=-1))
    return int((distance <= TOLERANCE).sum())


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("screenshot")
    parser.add_argument("--min-pixels", type=int, default=200)
    args = parser.parse_args()
    image = np.asarray(Image.open(args.screenshot).convert("RGB")).astype(int)
    background = (image == np.array(BACKGROUND)).all(axis=2)
    columns, rows = background.sum(axis=0), background.sum(axis=1)
    if columns.max() < 100:
        print("FAIL no 3D view: almost no pixel of the background colour %s" % (BACKGROUND,))
        return 1
    xs = np.nonzero(columns > 0.5 * columns.max())[0]
    ys = np.nonzero(rows > 0.5 * rows.max())[0]
    x0, x1, y0, y1 = xs.min(), xs.max(), ys.min(), ys.max()
    view = image[y0:y1 + 1, x0:x1 + 1]
    panel = image[:, ICON_COLUMNS:x0]
    ok = True
    print("3D view: x %d..%d, y %d..%d of %dx%d" % (x0, x1, y0, y1, image.shape[1], image.shape[0]))
    for name, colour in (("estimate", ESTIMATE), ("ground truth", GROUND_TRUTH)):
        n = count_near(view, colour)
        passed = n >= args.min_pixels
        ok = ok and passed
        print("%s %s colour %s: %d pixels in the 3D view (need %d)"
              % ("ok  " if passed else "FAIL", name, colour, n, args.min_pixels))
    if panel.shape[1] < 50:
        print("FAIL no panel left of the 3D view")
        return 1
    for name, is_colour in PANEL_COLOURS:
        n = int(is_colour(panel).sum())
        passed = n == 0
        ok = ok and passed
        print("%s panel %s status colour: %d pixels" % ("ok  " if passed else "FAIL", name, n))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
