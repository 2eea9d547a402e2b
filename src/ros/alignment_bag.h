// Reading a rosbag for calibrate_imu: a camera's images (raw or compressed) with its camera_info,
// and an IMU's sensor_msgs/Imu angular velocities. The interface is ROS-free (the command that uses
// it is), the implementation reads the bag with rosbag.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "visual_gyro/camera_model.h"
#include "visual_gyro/sequence.h"

namespace visual_gyro {
namespace alignment_bag {

/// The topics to read; "" takes the default.
struct Topics {
  std::string image;        ///< sensor_msgs/Image, or CompressedImage on <image>/compressed; default make_bag's
  std::string imu;          ///< sensor_msgs/Imu; default make_bag's
  std::string camera_info;  ///< default: camera_info beside the image topic (image_transport's rule)
};

/// The topics with every "" replaced by its default.
Topics withDefaults(const Topics& topics);

/// What a first pass over the bag finds.
struct Scan {
  std::vector<GyroSample> imu;      ///< header stamps [s] and angular_velocity [rad/s], in bag order
  std::vector<double> image_stamps;  ///< header stamps of the images [s], in bag order
  std::string camera_frame;          ///< frame_id of the first camera_info (else of the first image)
  std::string imu_frame;             ///< frame_id of the first Imu message
  /// A /tf_static transform imu_frame -> camera_frame in the bag (make_bag writes EuRoC's T_BS):
  /// its rotation, IMU <- camera.
  bool has_imu_from_camera = false;
  Eigen::Matrix3d imu_from_camera = Eigen::Matrix3d::Identity();
};

/// Reads the Imu samples, the images' stamps and /tf_static. Throws std::runtime_error when the bag cannot be
/// read, or holds no image on the topic (or its /compressed) or no camera_info.
Scan scanBag(const std::string& bag_path, const Topics& topics);

/// Called per image: the image as CV_8UC1, its header stamp [s], and the camera model of the latest
/// camera_info before it in bag order (the first camera_info for images before it).
using FrameCallback = std::function<void(const cv::Mat& gray, double stamp, const CameraModel& camera)>;

/// Decodes every image in bag order and hands it to `callback`. Returns how many images were
/// skipped (undecodable, or no usable camera_info), with the first reason in *first_problem.
int forEachImage(const std::string& bag_path, const Topics& topics, const FrameCallback& callback,
                 std::string* first_problem);

}  // namespace alignment_bag
}  // namespace visual_gyro
