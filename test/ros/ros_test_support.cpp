#include "ros_test_support.h"

#include <cmath>
#include <cstring>

#include <Eigen/Geometry>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <rosgraph_msgs/Log.h>

namespace visual_gyro {
namespace ros_test {

bool waitFor(const std::function<bool()>& pred, double timeout) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout);
  while (ros::ok() && ros::WallTime::now() < end) {
    if (pred()) return true;
    ros::WallDuration(0.005).sleep();
  }
  return pred();
}

RenderSettings handheldScene() {
  RenderSettings s;
  s.preset = RenderPreset::kHandheld;
  s.setCentredCamera(320, 240, 250.0);
  s.noise_sigma = 1.0;
  return s;
}

Eigen::Matrix3d yawRight(double yaw_deg) {
  return Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
}

const std::vector<cv::Mat>& turnViews() {
  static const std::vector<cv::Mat> views = [] {
    std::vector<cv::Mat> out;
    for (int k = 0; k < 12; ++k) out.push_back(renderView(handheldScene(), yawRight(k), Eigen::Vector3d::Zero()));
    return out;
  }();
  return views;
}

sensor_msgs::CameraInfo cameraInfo(const RenderSettings& s, const std::string& frame_id) {
  sensor_msgs::CameraInfo info;
  info.header.frame_id = frame_id;
  info.width = s.width;
  info.height = s.height;
  info.distortion_model = "plumb_bob";
  info.D.assign(5, 0.0);
  info.K = {s.fx, 0, s.cx, 0, s.fy, s.cy, 0, 0, 1};
  info.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  info.P = {s.fx, 0, s.cx, 0, 0, s.fy, s.cy, 0, 0, 0, 1, 0};
  return info;
}

sensor_msgs::Image imageMsg(const cv::Mat& image, const std::string& encoding, double stamp,
                            const std::string& frame_id) {
  sensor_msgs::Image msg;
  msg.header.stamp.fromSec(stamp);
  msg.header.frame_id = frame_id;
  msg.height = static_cast<uint32_t>(image.rows);
  msg.width = static_cast<uint32_t>(image.cols);
  msg.encoding = encoding;
  msg.is_bigendian = 0;
  msg.step = static_cast<uint32_t>(image.cols * image.elemSize());
  msg.data.resize(static_cast<size_t>(msg.step) * image.rows);
  for (int r = 0; r < image.rows; ++r)
    std::memcpy(&msg.data[static_cast<size_t>(r) * msg.step], image.ptr(r), msg.step);
  return msg;
}

void OutputRecorder::subscribeOutputs() {
  imu_sub_ = nh_.subscribe<sensor_msgs::Imu>(ns_ + "/imu", 100, [this](const sensor_msgs::ImuConstPtr& m) {
    std::lock_guard<std::mutex> l(mutex_);
    imu_msgs_.push_back(*m);
  });
  rotation_sub_ = nh_.subscribe<visual_gyro::RotationEstimate>(
      ns_ + "/rotation", 100, [this](const visual_gyro::RotationEstimateConstPtr& m) {
        std::lock_guard<std::mutex> l(mutex_);
        rotation_msgs_.push_back(*m);
      });
  orientation_sub_ = nh_.subscribe<geometry_msgs::PoseStamped>(
      ns_ + "/orientation", 100, [this](const geometry_msgs::PoseStampedConstPtr& m) {
        std::lock_guard<std::mutex> l(mutex_);
        orientation_msgs_.push_back(*m);
      });
}

OutputRecorder::~OutputRecorder() {
  // Subscriber::shutdown waits for a callback in progress, so after these no callback touches
  // the members below.
  unsubscribeOutputs();
  diag_sub_.shutdown();
  rosout_sub_.shutdown();
}

void OutputRecorder::unsubscribeOutputs() {
  imu_sub_.shutdown();
  rotation_sub_.shutdown();
  orientation_sub_.shutdown();
}

void OutputRecorder::watchDiagnosticsAndLogs() {
  diag_sub_ = nh_.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 100, [this](const diagnostic_msgs::DiagnosticArrayConstPtr& a) {
        std::lock_guard<std::mutex> l(mutex_);
        for (const auto& s : a->status)
          if (s.name.find("visual_gyro") != std::string::npos) diag_.emplace_back(s.level, s.message);
      });
  rosout_sub_ = nh_.subscribe<rosgraph_msgs::Log>("/rosout", 1000, [this](const rosgraph_msgs::LogConstPtr& m) {
    std::lock_guard<std::mutex> l(mutex_);
    if (m->name.find("visual_gyro") != std::string::npos) logs_.push_back(m->msg);
  });
}

int OutputRecorder::orientations() {
  std::lock_guard<std::mutex> l(mutex_);
  return static_cast<int>(orientation_msgs_.size());
}

std::vector<visual_gyro::RotationEstimate> OutputRecorder::rotations() {
  std::lock_guard<std::mutex> l(mutex_);
  return rotation_msgs_;
}

std::vector<sensor_msgs::Imu> OutputRecorder::imus() {
  std::lock_guard<std::mutex> l(mutex_);
  return imu_msgs_;
}

std::vector<geometry_msgs::PoseStamped> OutputRecorder::orientationMsgs() {
  std::lock_guard<std::mutex> l(mutex_);
  return orientation_msgs_;
}

std::vector<std::pair<int, std::string>> OutputRecorder::diagnostics() {
  std::lock_guard<std::mutex> l(mutex_);
  return diag_;
}

bool OutputRecorder::waitDiagnostic(int level, const std::string& needle, double timeout) {
  return waitFor(
      [&] {
        for (const auto& d : diagnostics())
          if (d.first == level && d.second.find(needle) != std::string::npos) return true;
        return false;
      },
      timeout);
}

int OutputRecorder::logLines(const std::string& needle) {
  std::lock_guard<std::mutex> l(mutex_);
  int n = 0;
  for (const auto& line : logs_)
    if (line.find(needle) != std::string::npos) ++n;
  return n;
}

void OutputRecorder::clear() {
  std::lock_guard<std::mutex> l(mutex_);
  rotation_msgs_.clear();
  imu_msgs_.clear();
  orientation_msgs_.clear();
  diag_.clear();
  logs_.clear();
}

frame_player::PlayerOptions playerUnderNamespace(const std::string& ns) {
  frame_player::PlayerOptions options;
  options.topics.image = ns + options.topics.image;
  options.topics.camera_info = ns + options.topics.camera_info;
  options.topics.ground_truth = ns + options.topics.ground_truth;
  options.output_ns = ns + options.output_ns;
  options.frame_timeout = 20.0;
  return options;
}

int runRosTests(int argc, char** argv, const char* node_name, int threads, const std::function<int()>& body) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, node_name);
  ros::AsyncSpinner spinner(threads);
  spinner.start();
  const int result = body();
  spinner.stop();
  // roscpp's own threads (poll, XML-RPC, connections) stop here, before static destruction frees
  // what they read.
  ros::shutdown();
  return result;
}

}  // namespace ros_test
}  // namespace visual_gyro
