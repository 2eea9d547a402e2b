#!/usr/bin/python3
"""rviz for real: scripts/rviz_shot.sh replays a short rendered bag through launch/replay.launch
with rviz and the real `rosbag play` under Xvfb, takes a screenshot, and scripts/check_rviz_shot.py
finds the estimate and ground-truth colours in the 3D view and no warning or error colour in the
Displays panel. The checker itself is tested on synthetic screenshots (it must be able to fail)."""
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import numpy as np
from PIL import Image

REPO = os.path.realpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
CHECK = os.path.join(REPO, "scripts", "check_rviz_shot.py")


def workspace():
    """The catkin workspace this test runs from (its devel space holds make_bag)."""
    for prefix in os.environ.get("CMAKE_PREFIX_PATH", "").split(":"):
        if prefix and os.path.exists(os.path.join(prefix, "lib", "visual_gyro", "make_bag")):
            return os.path.dirname(os.path.realpath(prefix))
    return None


def synthetic_screenshot(path, estimate=True, truth=True, warning=False):
    image = np.full((300, 400, 3), 239, dtype=np.uint8)  # panel grey
    image[20:290, 150:395] = (48, 48, 48)                 # 3D view
    if estimate:
        image[100:104, 160:300] = (25, 229, 25)
    if truth:
        image[150:156, 160:300] = (229, 51, 25)
    if warning:
        image[60:70, 50:120] = (192, 128, 0)               # "Global Status: Warn" text
    Image.fromarray(image).save(path)


class RvizShot(unittest.TestCase):
    def run_check(self, **kwargs):
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "shot.png")
            synthetic_screenshot(path, **kwargs)
            return subprocess.run([sys.executable, CHECK, path, "--min-pixels", "100"],
                                  stdout=subprocess.PIPE, universal_newlines=True)

    def test_good_screenshot_passes(self):
        result = self.run_check()
        self.assertEqual(result.returncode, 0, result.stdout)

    def test_missing_truth_line_fails(self):
        result = self.run_check(truth=False)
        self.assertEqual(result.returncode, 1, result.stdout)
        self.assertIn("FAIL ground truth", result.stdout)

    def test_panel_warning_fails(self):
        result = self.run_check(warning=True)
        self.assertEqual(result.returncode, 1, result.stdout)
        self.assertIn("FAIL panel warning", result.stdout)

    def test_rviz_screenshot_of_a_replayed_bag(self):
        for tool in ("rviz", "Xvfb", "import"):
            if shutil.which(tool) is None:
                self.skipTest("%s is not installed (scripts/install_deps.sh installs rviz, xvfb, imagemagick)" % tool)
        if "libasan" in os.environ.get("LD_PRELOAD", ""):
            self.skipTest("make sanitize preloads the ASan runtime into every process, rviz (third-party, OpenGL "
                          "under Xvfb) included, and rviz does not come up in time under it; this test runs for real "
                          "in make test")
        ws = workspace()
        self.assertIsNotNone(ws, "no devel space with visual_gyro's make_bag in CMAKE_PREFIX_PATH")
        out = tempfile.mkdtemp(prefix="visual_gyro_rviz_")
        env = dict(os.environ, VG_WS=ws, RVIZ_SHOT_OUT=out, FRAMES="30", RATE="1")
        env.pop("DATA", None)
        result = subprocess.run([os.path.join(REPO, "scripts", "rviz_shot.sh")], env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, universal_newlines=True, timeout=280)
        print(result.stdout)
        self.assertEqual(result.returncode, 0, "rviz_shot.sh failed:\n" + result.stdout[-3000:])
        shot = os.path.join(out, "replay.png")
        self.assertTrue(os.path.exists(shot))
        width, height = Image.open(shot).size
        self.assertEqual((width, height), (1400, 900))
        for line in ("ok   estimate colour", "ok   ground truth colour", "ok   panel warning", "ok   panel error"):
            self.assertIn(line, result.stdout)
        shutil.rmtree(out, ignore_errors=True)


if __name__ == "__main__":
    import rostest
    rostest.rosrun("visual_gyro", "test_rviz_shot", RvizShot, sys.argv)
