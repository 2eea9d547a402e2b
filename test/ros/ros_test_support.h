// Scaffolding shared by the ROS tests: bounded waits, the rendered test scene and its camera_info,
// image messages, a recorder of a node's outputs (/diagnostics and /rosout included) and main().
#pragma once

#include <functional>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <geometry_msgs/PoseStamped.h>
#include <opencv2/core.hpp>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include "frame_player.h"
#include "visual_gyro/RotationEstimate.h"
#include "visual_gyro/renderer.h"

namespace visual_gyro {
namespace ros_test {

/// Waits until pred() holds or `timeout` seconds pass (an AsyncSpinner delivers the messages).
bool waitFor(const std::function<bool()>& pred, double timeout);

/// The hand-held room around a 320x240 camera (f = 250 px, noise 1 grey level): rotation-only
/// views are well textured.
RenderSettings handheldScene();
/// Camera orientation (camera -> world) turned right by `yaw_deg` about the camera's +y (down).
Eigen::Matrix3d yawRight(double yaw_deg);
/// Views of the scene turning right by 1 degree per frame (12 views, rendered once).
const std::vector<cv::Mat>& turnViews();
/// The camera_info of `scene` (plumb_bob, zero distortion) in `frame_id`.
sensor_msgs::CameraInfo cameraInfo(const RenderSettings& scene, const std::string& frame_id);
/// `image` as a message of `encoding` (its bytes copied row by row), stamped `stamp` [s].
sensor_msgs::Image imageMsg(const cv::Mat& image, const std::string& encoding, double stamp,
                            const std::string& frame_id);

/// Subscribes to the outputs of the node in `ns` (imu, rotation, orientation) and, when asked,
/// to /diagnostics and /rosout (statuses and lines of nodes named *visual_gyro*); keeps them.
class OutputRecorder {
 public:
  explicit OutputRecorder(std::string ns) : ns_(std::move(ns)) {}
  /// Shuts every subscription down before the kept messages go: a callback still running on a
  /// spinner thread would otherwise write into freed vectors.
  virtual ~OutputRecorder();
  OutputRecorder(const OutputRecorder&) = delete;
  OutputRecorder& operator=(const OutputRecorder&) = delete;

  void subscribeOutputs();
  void unsubscribeOutputs();
  void watchDiagnosticsAndLogs();

  int orientations();
  std::vector<visual_gyro::RotationEstimate> rotations();
  std::vector<sensor_msgs::Imu> imus();
  std::vector<geometry_msgs::PoseStamped> orientationMsgs();
  /// Diagnostics statuses (level, message) received since the last clear().
  std::vector<std::pair<int, std::string>> diagnostics();
  /// Waits until a status of `level` whose message contains `needle` arrives.
  bool waitDiagnostic(int level, const std::string& needle, double timeout);
  /// Log lines containing `needle` since the last clear().
  int logLines(const std::string& needle);
  /// Forgets everything received so far.
  void clear();
  /// Waits briefly for the ~rotation/~imu messages published just before the last ~orientation.
  void settle() { ros::WallDuration(0.3).sleep(); }

 protected:
  ros::NodeHandle nh_;

 private:
  std::string ns_;
  ros::Subscriber imu_sub_, rotation_sub_, orientation_sub_, diag_sub_, rosout_sub_;
  std::mutex mutex_;
  std::vector<visual_gyro::RotationEstimate> rotation_msgs_;
  std::vector<sensor_msgs::Imu> imu_msgs_;
  std::vector<geometry_msgs::PoseStamped> orientation_msgs_;
  std::vector<std::pair<int, std::string>> diag_;
  std::vector<std::string> logs_;
};

/// Frame-by-frame player options for a node launched under namespace `ns` (e.g. "/compressed"):
/// the bag's default topics and the node's outputs moved under it, 20 s per frame.
frame_player::PlayerOptions playerUnderNamespace(const std::string& ns);

/// main() of a gtest with ROS: gtest and ROS initialised as `node_name`, an AsyncSpinner with
/// `threads` threads running around body() (which runs the tests and returns their result), then
/// ros::shutdown().
int runRosTests(int argc, char** argv, const char* node_name, int threads, const std::function<int()>& body);

}  // namespace ros_test
}  // namespace visual_gyro
