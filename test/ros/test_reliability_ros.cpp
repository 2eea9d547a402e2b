// Reliability of the node against bad ROS input: what it publishes (never a valid Imu from an
// implausible frame) and what /diagnostics and /rosout say. Publishes image and camera_info on
// separate publishers so that either can be missing or wrong. The tests share one node and run in
// order; each starts its stamps far after the previous test's (the node resets across the gap).
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Geometry>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <dynamic_reconfigure/Reconfigure.h>
#include <geometry_msgs/PoseStamped.h>
#include <nodelet/loader.h>
#include <opencv2/core.hpp>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/image_encodings.h>

#include "ros_test_support.h"
#include "visual_gyro/RotationEstimate.h"
#include "visual_gyro/calibration_fit.h"
#include "visual_gyro/renderer.h"

namespace {

using visual_gyro::RotationEstimate;
using visual_gyro::ros_test::waitFor;
namespace vgt = visual_gyro::ros_test;
namespace enc = sensor_msgs::image_encodings;
constexpr double kDeg = M_PI / 180.0;
const char* kNs = "/visual_gyro";

/// Views of a right turn, 1 degree per frame.
const std::vector<cv::Mat>& turn() { return vgt::turnViews(); }

/// Image and camera_info publishers (separate, so either can be missing or wrong) and the
/// recorder of the node's outputs, diagnostics and log lines.
class Harness : public vgt::OutputRecorder {
 public:
  Harness() : OutputRecorder(kNs) {
    image_pub_ = nh_.advertise<sensor_msgs::Image>("/rel_camera/image_raw", 5);
    info_pub_ = nh_.advertise<sensor_msgs::CameraInfo>("/rel_camera/camera_info", 5);
    info_ = vgt::cameraInfo(vgt::handheldScene(), "rel_camera_optical");
    subscribeOutputs();
    watchDiagnosticsAndLogs();
  }

  sensor_msgs::CameraInfo info() const { return info_; }

  /// Publishes an image (and, when `with_info`, the camera_info of the same stamp); true when the
  /// node answered with an ~orientation within `timeout` seconds.
  bool send(const cv::Mat& image, double stamp, double timeout = 5.0, const std::string& encoding = enc::MONO8,
            bool with_info = true, const sensor_msgs::CameraInfo* info_override = nullptr) {
    const sensor_msgs::Image msg = vgt::imageMsg(image, encoding, stamp, "rel_camera_optical");
    sensor_msgs::CameraInfo info = info_override ? *info_override : info_;
    info.header = msg.header;
    const int before = orientations();
    if (with_info) info_pub_.publish(info);
    image_pub_.publish(msg);
    return waitFor([&] { return orientations() > before; }, timeout);
  }

  bool connected(double timeout = 15.0) {
    return waitFor([&] { return image_pub_.getNumSubscribers() > 0 && info_pub_.getNumSubscribers() > 0; },
                   timeout);
  }

 private:
  ros::Publisher image_pub_, info_pub_;
  sensor_msgs::CameraInfo info_;
};

Harness* g_harness = nullptr;

/// Sends a change to the node's dynamic_reconfigure server through its service (not
/// dynamic_reconfigure::Client, whose configuration callback reads uninitialised bools of its
/// default-constructed config); *answer receives the settings the server now holds.
bool reconfigure(const dynamic_reconfigure::Config& change, dynamic_reconfigure::Config* answer = nullptr) {
  dynamic_reconfigure::Reconfigure srv;
  srv.request.config = change;
  if (!ros::service::waitForService(std::string(kNs) + "/set_parameters", 10000) ||
      !ros::service::call(std::string(kNs) + "/set_parameters", srv))
    return false;
  if (answer != nullptr) *answer = srv.response.config;
  return true;
}

/// One parameter of a reconfigure request (DoubleParameter, StrParameter, ...).
template <class Parameter, class Value>
Parameter parameter(const std::string& name, const Value& value) {
  Parameter p;
  p.name = name;
  p.value = value;
  return p;
}

/// Sets one double of the node's dynamic_reconfigure settings.
bool reconfigure(const std::string& name, double value, dynamic_reconfigure::Config* answer = nullptr) {
  dynamic_reconfigure::Config change;
  change.doubles.push_back(parameter<dynamic_reconfigure::DoubleParameter>(name, value));
  return reconfigure(change, answer);
}

/// Sets one boolean of the node's dynamic_reconfigure settings.
bool reconfigure(const std::string& name, bool value, dynamic_reconfigure::Config* answer = nullptr) {
  dynamic_reconfigure::Config change;
  change.bools.push_back(parameter<dynamic_reconfigure::BoolParameter>(name, value));
  return reconfigure(change, answer);
}

/// Sets one text setting of the node's dynamic_reconfigure settings.
bool reconfigure(const std::string& name, const std::string& value, dynamic_reconfigure::Config* answer = nullptr) {
  dynamic_reconfigure::Config change;
  change.strs.push_back(parameter<dynamic_reconfigure::StrParameter>(name, value));
  return reconfigure(change, answer);
}

/// The value of `name` among one type's parameters of a server's answer, or `absent`.
template <class Parameter, class Value>
Value valueIn(const std::vector<Parameter>& parameters, const std::string& name, const Value& absent) {
  for (const auto& p : parameters)
    if (p.name == name) return p.value;
  return absent;
}

using Level = diagnostic_msgs::DiagnosticStatus;

// Wall-clock bounds on the node's reactions are stretched by this factor in the sanitizer build
// (make sanitize), where the node and this test run several times slower and a tight bound would
// measure the instrumentation rather than the node.
#if defined(__SANITIZE_ADDRESS__)
constexpr double kSlowdown = 2.0;
#else
constexpr double kSlowdown = 1.0;
#endif

// Runs first: images arrive, camera_info never does.
TEST(ReliabilityRos, ImagesWithoutCameraInfoWarnWithinThreeSeconds) {
  Harness& h = *g_harness;
  ASSERT_TRUE(h.connected());
  h.clear();
  const ros::WallTime start = ros::WallTime::now();
  bool warned = false;
  for (int k = 0; k < 40 * kSlowdown && !warned; ++k) {
    EXPECT_FALSE(h.send(turn()[k % 12], 10.0 + 0.1 * k, 0.1, enc::MONO8, false)) << "an output without camera_info";
    for (const auto& d : h.diagnostics())
      warned = warned || (d.first == Level::WARN && d.second.find("camera_info") != std::string::npos);
  }
  EXPECT_TRUE(warned) << "no WARN naming camera_info";
  EXPECT_LT((ros::WallTime::now() - start).toSec(), 3.5 * kSlowdown)
      << "the WARN took longer than 3 s (+ publishing)" << (kSlowdown > 1.0 ? ", stretched for the sanitizers" : "");
}

TEST(ReliabilityRos, MicrosecondStepsNeverGiveAValidImu) {
  Harness& h = *g_harness;
  h.clear();
  const double t0 = 100.0;
  ASSERT_TRUE(h.send(turn()[0], t0));
  EXPECT_FALSE(h.send(turn()[1], t0 + 1e-6, 1.0)) << "a frame 1 us after the previous was used";
  EXPECT_FALSE(h.send(turn()[2], t0 + 1e-6 + 3e-9, 1.0)) << "a frame 3 ns after the previous was used";
  ASSERT_TRUE(h.send(turn()[2], t0 + 0.1));
  h.settle();
  for (const auto& imu : h.imus()) {
    const double rate = std::hypot(imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z);
    EXPECT_LT(rate, 1.0) << "an Imu at " << rate << " rad/s";
  }
  const auto rotations = h.rotations();
  ASSERT_EQ(rotations.size(), 1u);
  EXPECT_TRUE(rotations[0].valid) << rotations[0].status;
  EXPECT_NEAR(rotations[0].previous_stamp.toSec(), t0, 1e-6) << "the skipped frames were paired with";
  EXPECT_NEAR(rotations[0].yaw / kDeg, 2.0, 0.2);
  EXPECT_TRUE(h.waitDiagnostic(Level::WARN, "min_dt", 3.0)) << "no WARN naming min_dt";
}

TEST(ReliabilityRos, FrozenFrameNeverGivesAValidImu) {
  Harness& h = *g_harness;
  h.clear();
  const double t0 = 200.0;
  ASSERT_TRUE(h.send(turn()[0], t0));
  for (int k = 1; k <= 3; ++k) ASSERT_TRUE(h.send(turn()[0], t0 + 0.1 * k));
  h.settle();
  EXPECT_TRUE(h.imus().empty()) << "an Imu from a repeated frame";
  const auto rotations = h.rotations();
  ASSERT_EQ(rotations.size(), 3u);
  for (const auto& r : rotations) {
    EXPECT_FALSE(r.valid);
    EXPECT_NE(r.status.find("camera frozen?"), std::string::npos) << r.status;
  }
  EXPECT_TRUE(h.waitDiagnostic(Level::WARN, "camera frozen?", 3.0));
}

TEST(ReliabilityRos, BlackAndWhiteStreamsHaveNoTextureNotAFrozenCamera) {
  Harness& h = *g_harness;
  const double t0 = 250.0;
  for (const int grey : {0, 255}) {
    h.clear();
    const cv::Mat flat(turn()[0].size(), CV_8UC1, cv::Scalar(grey));
    // From the stream's first frame on; then after a textured frame, which stays the previous one.
    for (int k = 0; k < 3; ++k) EXPECT_TRUE(h.send(flat, t0 + 10.0 * (grey > 0) + 0.1 * k));
    ASSERT_TRUE(h.send(turn()[0], t0 + 10.0 * (grey > 0) + 0.3));
    for (int k = 4; k < 12; ++k) EXPECT_TRUE(h.send(flat, t0 + 10.0 * (grey > 0) + 0.1 * k));
    h.settle();
    EXPECT_TRUE(h.imus().empty()) << "an Imu from a textureless frame";
    const auto rotations = h.rotations();
    ASSERT_EQ(rotations.size(), 8u) << "grey " << grey;
    for (const auto& r : rotations) {
      EXPECT_FALSE(r.valid);
      EXPECT_EQ(r.status.rfind("no_texture: image has no texture", 0), 0u) << r.status;
    }
    EXPECT_TRUE(h.waitDiagnostic(Level::WARN, "no texture in", 3.0)) << "grey " << grey;
  }
}

// A camera slower than ~max_gap (0.8 Hz with the default 1 s): every frame resets, nothing is
// published, and /diagnostics says why and what max_gap would do. The stamps are 1.25 s apart;
// the frames are sent faster (the node judges gaps by the stamps).
TEST(ReliabilityRos, CameraSlowerThanMaxGapSaysWhichMaxGapWould) {
  Harness& h = *g_harness;
  h.clear();
  for (int k = 0; k < 8; ++k) h.send(turn()[k], 280.0 + 1.25 * k, 0.3);
  h.settle();
  EXPECT_TRUE(h.rotations().empty());
  EXPECT_TRUE(h.waitDiagnostic(Level::WARN, "exceeds max_gap (1 s): every frame resets the state, no output; "
                                            "set max_gap to at least 1.5 s",
                               3.0));
}

TEST(ReliabilityRos, Mono16RecoversOnTheNextNormalFrame) {
  Harness& h = *g_harness;
  h.clear();
  const double t0 = 300.0;
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 4; ++k) {
    cv::Mat m;
    turn()[k].convertTo(m, CV_16U, 16.0);  // a 12-bit camera
    frames.push_back(m);
  }
  frames[1].at<uint16_t>(5, 5) = 65535;  // one saturated pixel beyond 12 bits
  for (int k = 0; k < 4; ++k) ASSERT_TRUE(h.send(frames[k], t0 + 0.1 * k, 5.0, enc::MONO16));
  h.settle();
  const auto rotations = h.rotations();
  ASSERT_EQ(rotations.size(), 3u);
  // Frames 2 and 3 are normal again: their estimate is valid and right.
  EXPECT_TRUE(rotations[2].valid) << rotations[2].status;
  EXPECT_NEAR(rotations[2].yaw / kDeg, 1.0, 0.15);
  EXPECT_GT(rotations[2].features, 100u);
}

TEST(ReliabilityRos, ImplausibleCalibrationIsAnErrorWithNoOutput) {
  Harness& h = *g_harness;
  struct Case {
    const char* what;
    std::function<void(sensor_msgs::CameraInfo*)> change;
    const char* needle;
  };
  const std::vector<Case> cases = {
      {"principal point outside", [](sensor_msgs::CameraInfo* i) { i->K[2] = 5000.0; }, "principal point"},
      {"folding distortion", [](sensor_msgs::CameraInfo* i) { i->D = {-1.0, 0, 0, 0, 0}; }, "fold"},
      {"binning 1e6", [](sensor_msgs::CameraInfo* i) { i->binning_x = 1000000; }, "binning"},
      // Calibrations that gave confident, wrong rates on KITTI frames (the rendered camera's
      // corners lie about as far off axis as KITTI's).
      {"plumb_bob k1 = 5", [](sensor_msgs::CameraInfo* i) { i->D = {5.0, 0, 0, 0, 0}; },
       "plumb_bob distortion shrinks the field of view"},
      {"equidistant k1 = 3",
       [](sensor_msgs::CameraInfo* i) {
         i->distortion_model = "equidistant";
         i->D = {3.0, 0, 0, 0};
       },
       "equidistant distortion shrinks the field of view"},
      {"D = [50, -300, 1, 1, 900]", [](sensor_msgs::CameraInfo* i) { i->D = {50.0, -300.0, 1.0, 1.0, 900.0}; },
       "distortion"},
      {"principal point at the image corner",
       [](sensor_msgs::CameraInfo* i) {
         i->K[2] = i->width - 1.0;
         i->K[5] = i->height - 1.0;
       },
       "outside its central 60 %"},
  };
  double t = 400.0;
  for (const Case& c : cases) {
    h.clear();
    sensor_msgs::CameraInfo info = h.info();
    c.change(&info);
    for (int k = 0; k < 25; ++k, t += 0.1)
      EXPECT_FALSE(h.send(turn()[k % 12], t, 0.1, enc::MONO8, true, &info)) << c.what << ": an output";
    EXPECT_TRUE(h.waitDiagnostic(Level::ERROR, c.needle, 3.0)) << c.what << ": no ERROR naming '" << c.needle << "'";
    EXPECT_TRUE(h.rotations().empty()) << c.what;
    EXPECT_LE(h.logLines(c.needle), 1) << c.what << ": the error is logged more than once in 2.5 s";
    t += 10.0;
  }
  // A good camera again: outputs come back.
  ASSERT_TRUE(h.send(turn()[0], t));
  ASSERT_TRUE(h.send(turn()[1], t + 0.1));
}

// A calibration plausible by itself (plumb_bob k1 = 0.3) that the rendered images do not have: once
// the calibration check has seen enough frames, /diagnostics names camera_info and the estimates,
// still published, carry an inflated covariance; a fitting camera_info clears the warning.
TEST(ReliabilityRos, CalibrationThatDoesNotFitTheImagesWarnsAndInflates) {
  Harness& h = *g_harness;
  h.clear();
  sensor_msgs::CameraInfo info = h.info();
  info.D = {0.3, 0.0, 0.0, 0.0, 0.0};
  // The views turn right and back (1 deg per frame).
  auto view = [](int k) { return turn()[k % 22 < 12 ? k % 22 : 22 - k % 22]; };
  double t = 520.0;
  for (int k = 0; k < 30; ++k, t += 0.1) ASSERT_TRUE(h.send(view(k), t, 5.0, enc::MONO8, true, &info));
  h.settle();
  const auto rotations = h.rotations();
  ASSERT_EQ(rotations.size(), 29u);
  for (const auto& r : rotations) EXPECT_TRUE(r.valid) << r.status;
  EXPECT_EQ(h.imus().size(), rotations.size());
  EXPECT_TRUE(h.waitDiagnostic(Level::WARN, "camera_info's distortion or intrinsics may not fit the images", 3.0));
  EXPECT_TRUE(h.waitDiagnostic(Level::WARN, "calibration does not fit the images, covariance inflated", 3.0));
  EXPECT_EQ(h.logLines("calibration does not fit the images"), 1) << "logged more than once";
  // The camera's own calibration: the check starts afresh, estimates are valid.
  h.clear();
  t += 10.0;
  for (int k = 0; k < 3; ++k, t += 0.1) ASSERT_TRUE(h.send(view(k), t));
  h.settle();
  ASSERT_EQ(h.rotations().size(), 2u);
  for (const auto& r : h.rotations()) EXPECT_TRUE(r.valid) << r.status;
}

TEST(ReliabilityRos, CameraInfoChangingEveryFrameIsAResetStorm) {
  Harness& h = *g_harness;
  h.clear();
  double t = 600.0;
  for (int k = 0; k < 30; ++k, t += 0.1) {
    sensor_msgs::CameraInfo info = h.info();
    info.K[0] = info.K[4] = 250.0 + (k % 2);
    h.send(turn()[k % 12], t, 2.0, enc::MONO8, true, &info);
  }
  EXPECT_TRUE(h.waitDiagnostic(Level::WARN, "reset storm", 3.0));
  EXPECT_TRUE(h.waitDiagnostic(Level::WARN, "camera_info changed", 1.0));
  EXPECT_LE(h.logLines("camera changed"), 1) << "the camera-change line is not throttled";
}

TEST(ReliabilityRos, MaxGapBelowTheFrameIntervalIsAResetStorm) {
  Harness& h = *g_harness;
  ASSERT_TRUE(reconfigure("max_gap", 0.05));
  h.clear();
  double t = 700.0;
  for (int k = 0; k < 30; ++k, t += 0.1) h.send(turn()[k % 12], t, 2.0);
  EXPECT_TRUE(h.waitDiagnostic(Level::WARN, "max_gap", 3.0));
  EXPECT_LE(h.logLines("exceeds ~max_gap"), 1) << "the gap warning is not throttled";
  EXPECT_TRUE(h.rotations().empty());
  ASSERT_TRUE(reconfigure("max_gap", 1.0));
}

TEST(ReliabilityRos, MaxRateIsLiveAndNamesTheReason) {
  Harness& h = *g_harness;
  ASSERT_TRUE(reconfigure("max_rate_dps", 5.0));  // the views turn at 10 deg/s
  h.clear();
  const double t0 = 800.0;
  for (int k = 0; k < 3; ++k) ASSERT_TRUE(h.send(turn()[k], t0 + 0.1 * k));
  h.settle();
  EXPECT_TRUE(h.imus().empty());
  const auto rotations = h.rotations();
  ASSERT_EQ(rotations.size(), 2u);
  for (const auto& r : rotations) EXPECT_NE(r.status.find("max_rate_dps"), std::string::npos) << r.status;
  ASSERT_TRUE(reconfigure("max_rate_dps", 2000.0));
  ASSERT_TRUE(h.send(turn()[3], t0 + 0.3));
  h.settle();
  ASSERT_EQ(h.rotations().size(), 3u);
  EXPECT_TRUE(h.rotations().back().valid) << h.rotations().back().status;
}

TEST(ReliabilityRos, TooFineBinsAreWidenedLive) {
  Harness& h = *g_harness;
  h.clear();
  // The least bin the settings accept, far too fine for the window: the estimator widens it to fit
  // its window, so the change is accepted and the frames are still estimated.
  ASSERT_TRUE(reconfigure("rotation_bin_deg", 0.01));
  const double t0 = 900.0;
  for (int k = 0; k < 3; ++k) ASSERT_TRUE(h.send(turn()[k], t0 + 0.1 * k));
  h.settle();
  const auto rotations = h.rotations();
  ASSERT_EQ(rotations.size(), 2u);
  for (const auto& r : rotations) {
    EXPECT_TRUE(r.valid) << r.status;
    EXPECT_GT(r.matches, 100u);
  }
  EXPECT_EQ(h.logLines("rejected settings"), 0);
  ASSERT_TRUE(reconfigure("rotation_bin_deg", 0.5));
}

TEST(ReliabilityRos, RejectedLiveChangeKeepsThePreviousSettingsAndWarns) {
  Harness& h = *g_harness;
  h.clear();
  std::string before_method;
  double before_window = 0.0;
  ASSERT_TRUE(ros::param::get(std::string(kNs) + "/method", before_method));
  ASSERT_TRUE(ros::param::get(std::string(kNs) + "/rotation_window_deg", before_window));
  // The server clamps nothing (the cfg gives no ranges): a method the settings table does not know
  // reaches the node, whose gate refuses it.
  dynamic_reconfigure::Config answer;
  ASSERT_TRUE(reconfigure("method", std::string("nonsense"), &answer));
  // The server answers, publishes and stores the settings still in use.
  EXPECT_EQ(valueIn(answer.strs, "method", std::string()), before_method);
  std::string stored_method;
  ASSERT_TRUE(ros::param::get(std::string(kNs) + "/method", stored_method));
  EXPECT_EQ(stored_method, before_method) << "the parameter server holds the rejected value";
  // One error line naming the setting, and a WARN on /diagnostics until a change is accepted.
  EXPECT_TRUE(waitFor([&] { return h.logLines("rejected settings change method vote -> nonsense") > 0; }, 3.0));
  EXPECT_EQ(h.logLines("rejected settings change"), 1);
  EXPECT_TRUE(h.waitDiagnostic(Level::WARN, "rejected settings change: method", 3.0));
  const double t0 = 1000.0;
  for (int k = 0; k < 3; ++k) ASSERT_TRUE(h.send(turn()[k], t0 + 0.1 * k));
  h.settle();
  for (const auto& r : h.rotations()) EXPECT_TRUE(r.valid) << r.status;
  EXPECT_TRUE(h.waitDiagnostic(Level::WARN, "rejected settings change", 3.0)) << "the WARN did not last";

  ASSERT_TRUE(reconfigure("rotation_window_deg", 8.0, &answer));
  EXPECT_EQ(valueIn(answer.doubles, "rotation_window_deg", std::nan("")), 8.0);
  h.clear();
  EXPECT_TRUE(waitFor(
      [&] {
        const auto d = h.diagnostics();
        return !d.empty() && d.back().second.find("rejected") == std::string::npos;
      },
      3.0))
      << "the WARN outlived an accepted change";
  double stored = 0.0;
  ASSERT_TRUE(ros::param::get(std::string(kNs) + "/rotation_window_deg", stored));
  EXPECT_EQ(stored, 8.0);
  ASSERT_TRUE(reconfigure("rotation_window_deg", before_window));
}

// The live gate: NaN, infinities and values out of range reach the node (the server clamps
// nothing), which refuses each, names it and answers with the value in force.
TEST(ReliabilityRos, NanInvalidVarianceIsRefusedAndTheImuCovarianceStaysFinite) {
  Harness& h = *g_harness;
  ASSERT_TRUE(reconfigure("publish_invalid", true));
  ASSERT_TRUE(reconfigure("max_rate_dps", 5.0));  // the views turn at 10 deg/s: every estimate is invalid
  h.clear();
  dynamic_reconfigure::Config answer;
  ASSERT_TRUE(reconfigure("invalid_variance", std::nan(""), &answer));
  EXPECT_EQ(valueIn(answer.doubles, "invalid_variance", 0.0), 1.0) << "the answer is not the value in force";
  double stored = 0.0;
  ASSERT_TRUE(ros::param::get(std::string(kNs) + "/invalid_variance", stored));
  EXPECT_EQ(stored, 1.0) << "the parameter server holds the refused value";
  EXPECT_TRUE(waitFor([&] { return h.logLines("rejected settings change invalid_variance 1 -> nan") > 0; }, 3.0));
  EXPECT_TRUE(h.waitDiagnostic(Level::WARN, "invalid_variance", 3.0));
  const double t0 = 1100.0;
  for (int k = 0; k < 3; ++k) ASSERT_TRUE(h.send(turn()[k], t0 + 0.1 * k));
  h.settle();
  const auto imus = h.imus();
  ASSERT_EQ(imus.size(), 2u) << "publish_invalid: one Imu per invalid estimate";
  for (const auto& imu : imus) {
    for (const double c : imu.angular_velocity_covariance) EXPECT_TRUE(std::isfinite(c));
    EXPECT_EQ(imu.angular_velocity_covariance[0], 1.0);
  }
  ASSERT_TRUE(reconfigure("max_rate_dps", 2000.0));
  ASSERT_TRUE(reconfigure("publish_invalid", false));
}

TEST(ReliabilityRos, ZeroNegativeAndTooSmallValuesAreRefusedNotClamped) {
  Harness& h = *g_harness;
  struct Case {
    const char* name;
    double value, in_force;
    const char* needle;
  };
  const std::vector<Case> cases = {
      {"invalid_variance", 0.0, 1.0, "invalid_variance must be in (0, 1000000]"},
      {"invalid_variance", -1.0, 1.0, "invalid_variance must be in (0, 1000000]"},
      {"rotation_bin_deg", 1e-12, 0.5, "rotation_bin_deg must be in [0.01, 10] deg"},
      {"max_gap", std::numeric_limits<double>::infinity(), 1.0, "max_gap must be in [0.001, 3600] s, got inf"},
  };
  for (const Case& c : cases) {
    h.clear();
    dynamic_reconfigure::Config answer;
    ASSERT_TRUE(reconfigure(c.name, c.value, &answer));
    EXPECT_EQ(valueIn(answer.doubles, c.name, std::nan("")), c.in_force) << c.name << " " << c.value;
    EXPECT_TRUE(waitFor([&] { return h.logLines(c.needle) > 0; }, 3.0)) << "no error line '" << c.needle << "'";
  }
}

TEST(ReliabilityRos, NanMaxGapIsRefusedAndAGapStillResets) {
  Harness& h = *g_harness;
  dynamic_reconfigure::Config answer;
  ASSERT_TRUE(reconfigure("max_gap", std::nan(""), &answer));
  EXPECT_EQ(valueIn(answer.doubles, "max_gap", 0.0), 1.0);
  h.clear();
  const double t0 = 1200.0;
  ASSERT_TRUE(h.send(turn()[0], t0));
  ASSERT_TRUE(h.send(turn()[1], t0 + 0.1));
  ASSERT_TRUE(h.send(turn()[2], t0 + 60.1));  // 60 s later: the state resets, no estimate
  ASSERT_TRUE(h.send(turn()[3], t0 + 60.2));
  h.settle();
  const auto rotations = h.rotations();
  ASSERT_EQ(rotations.size(), 2u) << "the frame after the gap was paired across it";
  EXPECT_NEAR(rotations[1].previous_stamp.toSec(), t0 + 60.1, 1e-6);
  for (const auto& r : rotations) EXPECT_TRUE(r.valid) << r.status;
  EXPECT_EQ(h.imus().size(), 2u);
}

// A nodelet manager unloads the nodelet while images stream in (the manager's unload service, a
// bond broken by the launching process): every callback source stops before the members it reads
// go. Three load/unload cycles in this process; make sanitize runs it under AddressSanitizer. Last in
// this file: the nodelet loaded here publishes diagnostics of its own.
TEST(ReliabilityRos, NodeletUnloadedWhileImagesStreamIn) {
  const std::string name = "/unload_gyro";
  ros::NodeHandle nh;
  ros::Publisher image_pub = nh.advertise<sensor_msgs::Image>("/unload_camera/image_raw", 5);
  ros::Publisher info_pub = nh.advertise<sensor_msgs::CameraInfo>("/unload_camera/camera_info", 5);
  const sensor_msgs::CameraInfo info = vgt::cameraInfo(vgt::handheldScene(), "unload_camera_optical");
  ros::param::set(name + "/backend", "cpu");
  nodelet::Loader loader(false);  // in this process, without the manager's services
  const nodelet::M_string remappings = {{"/image", "/unload_camera/image_raw"}};
  double stamp = 5000.0;
  for (int cycle = 0; cycle < 3; ++cycle) {
    ASSERT_TRUE(loader.load(name, "visual_gyro/VisualGyroNodelet", remappings, nodelet::V_string()));
    std::atomic<int> answers{0};
    ros::Subscriber orientation_sub = nh.subscribe<geometry_msgs::PoseStamped>(
        name + "/orientation", 10, [&answers](const geometry_msgs::PoseStampedConstPtr&) { ++answers; });
    ASSERT_TRUE(waitFor([&] { return image_pub.getNumSubscribers() > 0 && info_pub.getNumSubscribers() > 0; }, 15.0))
        << "cycle " << cycle << ": the loaded nodelet did not subscribe";
    ros::WallDuration(0.3).sleep();
    // Frames every 5 ms from another thread, so that some are in the nodelet's queue or being
    // processed when it is unloaded.
    std::atomic<bool> streaming{true};
    std::thread publisher([&] {
      for (size_t k = 0; streaming; ++k) {
        const sensor_msgs::Image image =
            vgt::imageMsg(turn()[k % turn().size()], enc::MONO8, stamp + 0.1 * k, "unload_camera_optical");
        sensor_msgs::CameraInfo stamped = info;
        stamped.header = image.header;
        info_pub.publish(stamped);
        image_pub.publish(image);
        ros::WallDuration(0.005).sleep();
      }
    });
    const bool answered = waitFor([&] { return answers >= 2; }, 20.0);
    EXPECT_TRUE(loader.unload(name)) << "cycle " << cycle;
    streaming = false;
    publisher.join();
    EXPECT_TRUE(answered) << "cycle " << cycle << ": the nodelet answered " << answers << " frames";
    orientation_sub.shutdown();
    EXPECT_TRUE(waitFor([&] { return image_pub.getNumSubscribers() == 0; }, 15.0))
        << "cycle " << cycle << ": the unloaded nodelet still subscribes to the images";
    stamp += 1000.0;
  }
}

}  // namespace

int main(int argc, char** argv) {
  return vgt::runRosTests(argc, argv, "test_reliability_ros", 2, [] {
    Harness harness;
    g_harness = &harness;
    const int result = RUN_ALL_TESTS();
    g_harness = nullptr;
    return result;
  });
}
