// The node's diagnostics summary without a ROS master: which cause wins, at which level.
#include <gtest/gtest.h>

#include <diagnostic_msgs/DiagnosticStatus.h>

#include "node_diagnostics.h"

using visual_gyro::NodeDiagnostics;
using Level = diagnostic_msgs::DiagnosticStatus;

namespace {

NodeDiagnostics::Context subscribed() {
  NodeDiagnostics::Context c;
  c.subscribed = true;
  c.image_topic = "/cam/image_raw";
  c.info_topic = "/cam/camera_info";
  c.backend_used = visual_gyro::Backend::kCpu;
  return c;
}

diagnostic_updater::DiagnosticStatusWrapper fill(NodeDiagnostics* d, double now,
                                                 const NodeDiagnostics::Context& c = subscribed()) {
  diagnostic_updater::DiagnosticStatusWrapper s;
  d->fill(s, now, c);
  return s;
}

std::string value(const diagnostic_updater::DiagnosticStatusWrapper& s, const std::string& key) {
  for (const auto& kv : s.values)
    if (kv.key == key) return kv.value;
  return "";
}

}  // namespace

TEST(NodeDiagnostics, HealthyStreamIsOkWithRates) {
  NodeDiagnostics d(0.0);
  for (int k = 0; k < 10; ++k) {
    d.imageIn(100.0 + 0.1 * k);
    d.processed();
    if (k > 0) d.estimatePublished(true, "", 8.0, 500, 0.3, /*half_resolution=*/k % 3 == 0);
  }
  const auto s = fill(&d, 1.0);
  EXPECT_EQ(s.level, Level::OK) << s.message;
  // Estimates 3, 6 and 9 of the nine came from half resolution.
  EXPECT_NEAR(std::stod(value(s, "Half-resolution pairs [%]")), 100.0 / 3.0, 1e-3);
  EXPECT_NEAR(std::stod(value(s, "Expected rate [Hz] (image stamps)")), 10.0, 1e-6);
  EXPECT_NEAR(std::stod(value(s, "Estimates out [Hz]")), 9.0, 1e-6);
  // The next window has no input: waiting, OK.
  EXPECT_EQ(fill(&d, 2.0).message, "subscribed, waiting for images");
  NodeDiagnostics::Context idle;
  EXPECT_EQ(fill(&d, 3.0, idle).message, "idle: no output subscribers");
}

TEST(NodeDiagnostics, UnusableSettingsAndCameraAreErrors) {
  NodeDiagnostics d(0.0);
  d.setSettingsProblem("~mono16_bit_depth must be 0 (per frame) or 8..16, got 5");
  auto s = fill(&d, 1.0);
  EXPECT_EQ(s.level, Level::ERROR);
  EXPECT_NE(s.message.find("mono16_bit_depth"), std::string::npos) << s.message;
  d.setSettingsProblem("");
  d.setCameraProblem("implausible calibration: principal point (5000, 120) lies outside");
  d.imageIn(1.0);
  d.skipped("camera");
  s = fill(&d, 2.0);
  EXPECT_EQ(s.level, Level::ERROR);
  EXPECT_NE(s.message.find("principal point"), std::string::npos) << s.message;
}

TEST(NodeDiagnostics, MissingCameraInfoIsNamed) {
  NodeDiagnostics d(0.0);
  d.probedInput(10, 0);
  auto s = fill(&d, 1.0);
  EXPECT_EQ(s.level, Level::WARN);
  EXPECT_NE(s.message.find("no camera_info on /cam/camera_info"), std::string::npos) << s.message;
  d.probedInput(10, 10);  // camera_info comes, with other stamps
  s = fill(&d, 2.0);
  EXPECT_EQ(s.level, Level::WARN);
  EXPECT_NE(s.message.find("stamps differ"), std::string::npos) << s.message;
}

TEST(NodeDiagnostics, ResetStormsAndInvalidEstimatesWarn) {
  NodeDiagnostics d(0.0);
  for (int k = 0; k < 10; ++k) {
    d.imageIn(10.0 + 0.1 * k);
    d.reset("camera_info changed");
    d.processed();
  }
  auto s = fill(&d, 1.0);
  EXPECT_EQ(s.level, Level::WARN);
  EXPECT_NE(s.message.find("reset storm"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("camera_info changed"), std::string::npos) << s.message;
  // The storm is judged over the last 5 s: a healthy window right after it still names it.
  for (int k = 0; k < 10; ++k) {
    d.imageIn(20.0 + 0.1 * k);
    d.processed();
    d.estimatePublished(true, "", 5.0, 500, 0.3);
  }
  s = fill(&d, 2.0);
  EXPECT_NE(s.message.find("reset storm: 10 resets for 20 images in the last 5 s"), std::string::npos) << s.message;
  // Once it has left the span, invalid estimates are the cause.
  for (int k = 0; k < 10; ++k) {
    d.imageIn(30.0 + 0.1 * k);
    d.processed();
    d.estimatePublished(false, "too few matches: 3", 5.0, 3, 0.0);
  }
  s = fill(&d, 7.5);
  EXPECT_EQ(s.level, Level::WARN);
  EXPECT_NE(s.message.find("too few matches"), std::string::npos) << s.message;
}

// Time jumping back every second frame at 3 Hz: one or two resets per 1-s window, which one
// window alone does not call a storm; the last 5 s do, in every window.
TEST(NodeDiagnostics, ResetStormsAreJudgedOverSeveralSeconds) {
  NodeDiagnostics d(0.0);
  int storms = 0;
  for (int second = 0; second < 8; ++second) {
    for (int i = 0; i < 3; ++i) {
      const int n = 3 * second + i;
      d.imageIn(100.0 + n / 3.0 - (n % 2 == 1 ? 0.5 : 0.0));
      d.processed();
      if (n % 2 == 1) {
        d.reset("time jumped back");
      } else if (n > 0) {
        d.estimatePublished(true, "", 5.0, 500, 0.3);
      }
    }
    const auto s = fill(&d, second + 1.0);
    if (second >= 2) {
      EXPECT_EQ(s.level, Level::WARN) << "second " << second << ": " << s.message;
      EXPECT_NE(s.message.find("reset storm"), std::string::npos) << "second " << second << ": " << s.message;
      EXPECT_NE(s.message.find("time jumped back"), std::string::npos) << s.message;
    }
    storms += s.message.find("reset storm") != std::string::npos;
  }
  EXPECT_GE(storms, 6);
  // A replayed bag looping every 2 s at 10 Hz resets too, but is no storm.
  NodeDiagnostics loop(0.0);
  for (int second = 0; second < 8; ++second) {
    for (int i = 0; i < 10; ++i) {
      loop.imageIn(100.0 + (10 * second + i) % 20 * 0.1);
      loop.processed();
      if ((10 * second + i) % 20 == 0) {
        loop.reset("time jumped back");
      } else {
        loop.estimatePublished(true, "", 5.0, 500, 0.3);
      }
    }
    const auto s = fill(&loop, second + 1.0);
    EXPECT_EQ(s.level, Level::OK) << "second " << second << ": " << s.message;
  }
}

// A 0.8 Hz camera with the default max_gap of 1 s resets on every frame and publishes nothing:
// a WARN that says so and suggests a max_gap, also in the windows without an image.
TEST(NodeDiagnostics, CameraSlowerThanMaxGapWarnsWithAValueThatWould) {
  NodeDiagnostics d(0.0);
  NodeDiagnostics::Context c = subscribed();
  c.max_gap = 1.0;
  int warned = 0, windows = 0;
  double next_image = 0.0;
  int images = 0;
  for (int second = 1; second <= 10; ++second) {
    for (; next_image < second; next_image += 1.25, ++images) {
      d.imageIn(50.0 + next_image);
      if (images > 0) d.reset("gap of 1.250000 s above max_gap 1.000000 s");
      d.processed();
    }
    const auto s = fill(&d, second, c);
    if (images < 3) continue;
    ++windows;
    EXPECT_EQ(s.level, Level::WARN) << s.message;
    EXPECT_NE(s.message.find("the camera's interval of 1.25 s (0.8 Hz) exceeds max_gap (1 s)"), std::string::npos)
        << s.message;
    warned += s.message.find("set max_gap to at least 1.5 s") != std::string::npos;
  }
  EXPECT_EQ(warned, windows);
  EXPECT_GE(windows, 7);
  // With max_gap raised the same camera is fine: no reset, no warning.
  NodeDiagnostics ok(0.0);
  c.max_gap = 1.5;
  for (int k = 0; k < 8; ++k) {
    ok.imageIn(50.0 + 1.25 * k);
    ok.processed();
    if (k > 0) ok.estimatePublished(true, "", 5.0, 500, 0.3);
    const auto s = fill(&ok, 1.25 * (k + 1), c);
    EXPECT_EQ(s.message.find("max_gap"), std::string::npos) << s.message;
  }
}

TEST(NodeDiagnostics, NoTextureIsNotAFrozenCamera) {
  NodeDiagnostics d(0.0);
  for (int k = 0; k < 10; ++k) {
    d.imageIn(100.0 + 0.1 * k);
    d.processed();
    d.noTexture("image has no texture (grey levels 0 +- 0): lens cap, darkness or overexposure?");
  }
  auto s = fill(&d, 1.0);
  EXPECT_EQ(s.level, Level::WARN);
  EXPECT_NE(s.message.find("no texture in 10 of 10 image(s)"), std::string::npos) << s.message;
  EXPECT_EQ(s.message.find("frozen"), std::string::npos) << s.message;
  EXPECT_EQ(value(s, "Images without texture"), "10");
  // A textured image repeated: the frozen camera, from its invalid estimates.
  for (int k = 0; k < 10; ++k) {
    d.imageIn(110.0 + 0.1 * k);
    d.processed();
    d.estimatePublished(false, "frozen_image: image identical to the previous one (camera frozen?)", 5.0, 0, 0.0);
  }
  s = fill(&d, 2.0);
  EXPECT_EQ(s.level, Level::WARN);
  EXPECT_NE(s.message.find("camera frozen?"), std::string::npos) << s.message;
  EXPECT_EQ(s.message.find("no texture"), std::string::npos) << s.message;
}

TEST(NodeDiagnostics, CalibrationMismatchWarnsUntilCleared) {
  NodeDiagnostics d(0.0);
  const std::string why = "residuals of neighbouring matches agree (correlation 0.62 over the last 20 frames; ...)";
  d.setCalibrationMismatch(why);
  for (int k = 0; k < 10; ++k) {
    d.imageIn(100.0 + 0.1 * k);
    d.processed();
    d.estimatePublished(true, "", 5.0, 500, 0.3);
  }
  auto s = fill(&d, 1.0);
  EXPECT_EQ(s.level, Level::WARN);
  EXPECT_EQ(s.message, "calibration does not fit the images, covariance inflated: " + why);
  EXPECT_EQ(value(s, "Calibration mismatch"), why);
  d.setCalibrationMismatch("");
  for (int k = 0; k < 10; ++k) {
    d.imageIn(101.0 + 0.1 * k);
    d.processed();
    d.estimatePublished(true, "", 5.0, 500, 0.3);
  }
  s = fill(&d, 2.0);
  EXPECT_EQ(s.level, Level::OK) << s.message;
}

TEST(NodeDiagnostics, RejectedChangeWarnsUntilAChangeIsAccepted) {
  NodeDiagnostics d(0.0);
  d.setRejectedChange("rotation_window_deg 6 -> 90: rotation_window_deg must be in (0, 90)");
  for (int k = 0; k < 10; ++k) {
    d.imageIn(100.0 + 0.1 * k);
    d.processed();
    d.estimatePublished(true, "", 5.0, 500, 0.5);
  }
  auto s = fill(&d, 1.0);
  EXPECT_EQ(s.level, Level::WARN);
  EXPECT_EQ(s.message, "rejected settings change: rotation_window_deg 6 -> 90: rotation_window_deg must be in (0, 90)");
  EXPECT_EQ(value(s, "Rejected settings change"), "rotation_window_deg 6 -> 90: rotation_window_deg must be in (0, 90)");
  // Unusable settings (no output at all) still win.
  d.setSettingsProblem("bad");
  EXPECT_EQ(fill(&d, 2.0).level, Level::ERROR);
  d.setSettingsProblem("");
  d.setRejectedChange("");
  EXPECT_EQ(fill(&d, 3.0).message.find("rejected"), std::string::npos);
}
