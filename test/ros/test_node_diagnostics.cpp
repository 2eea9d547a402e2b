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
  c.backend_used = "cpu";
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
  for (int k = 0; k < 10; ++k) {
    d.imageIn(20.0 + 0.1 * k);
    d.processed();
    d.estimatePublished(false, "too few matches: 3", 5.0, 3, 0.0);
  }
  s = fill(&d, 2.0);
  EXPECT_EQ(s.level, Level::WARN);
  EXPECT_NE(s.message.find("too few matches"), std::string::npos) << s.message;
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
