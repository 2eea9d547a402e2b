// Start-up parameters through the settings gate: the node of settings_startup.test starts with
// values that are out of range, NaN, infinite or not of their type; each is refused, replaced by
// its default (on the parameter server too, so that dynamic_reconfigure starts from the values in
// force) and named on /diagnostics.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <ros/ros.h>

#include "ros_test_support.h"

namespace {

namespace vgt = visual_gyro::ros_test;
using Level = diagnostic_msgs::DiagnosticStatus;
const std::string kNs = "/visual_gyro";

/// True once the parameter `name` of the node holds `expected` (the node has read its parameters).
template <class T>
bool becomes(const std::string& name, const T& expected, double timeout) {
  return vgt::waitFor(
      [&] {
        T value{};
        return ros::param::get(kNs + "/" + name, value) && value == expected;
      },
      timeout);
}

TEST(SettingsStartup, RefusedValuesAreReplacedByTheirDefaultsAndNamed) {
  vgt::OutputRecorder recorder(kNs);
  recorder.watchDiagnosticsAndLogs();
  EXPECT_TRUE(becomes("queue_size", 1, 30.0)) << "queue_size 0 was not replaced by its default";
  EXPECT_TRUE(becomes("mono16_bit_depth", 0, 5.0));
  EXPECT_TRUE(becomes("invalid_variance", 1.0, 5.0));
  EXPECT_TRUE(becomes("max_gap", 1.0, 5.0)) << "NaN max_gap was not replaced by its default";
  EXPECT_TRUE(becomes("use_camera_info", true, 5.0));
  EXPECT_TRUE(becomes("D", std::vector<double>(), 5.0));
  // A start-up parameter that the gate accepts is left as it was given.
  std::string backend;
  ASSERT_TRUE(ros::param::get(kNs + "/backend", backend));
  EXPECT_EQ(backend, "cpu");
  for (const char* name : {"queue_size", "mono16_bit_depth", "invalid_variance", "max_gap", "use_camera_info", "D"})
    EXPECT_TRUE(recorder.waitDiagnostic(Level::WARN, name, 5.0)) << "no WARN naming " << name;
}

}  // namespace

int main(int argc, char** argv) {
  return vgt::runRosTests(argc, argv, "test_settings_startup_ros", 1, [] { return RUN_ALL_TESTS(); });
}
