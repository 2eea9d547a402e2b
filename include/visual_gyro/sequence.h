// Reading image sequences with ground truth: the KITTI odometry layout and the EuRoC ASL layout.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "visual_gyro/camera_model.h"

namespace visual_gyro {

/// One gyro sample.
struct GyroSample {
  double stamp = 0.0;                                  ///< [s]
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  ///< [rad/s], IMU (body) frame
};

/// A sequence of grayscale images with whatever ground truth the folder holds.
struct Sequence {
  std::string name;                ///< folder name, e.g. "kitti_turn"
  std::string layout;              ///< "kitti" or "euroc"
  CameraModel camera;
  std::vector<std::string> image_paths;  ///< in time order
  std::vector<double> stamps;            ///< [s], one per image
  /// Camera orientation per image (camera frame -> first camera frame), when poses exist; NaN for
  /// an image outside the ground truth's time span.
  std::vector<Eigen::Matrix3d> orientations;
  /// Camera position per image [m], when poses exist.
  std::vector<Eigen::Vector3d> positions;
  std::vector<GyroSample> gyro;           ///< EuRoC: imu0 samples; else empty
  Eigen::Matrix3d body_from_camera = Eigen::Matrix3d::Identity();  ///< EuRoC T_BS rotation
  /// Where the ground truth comes from: "kitti_poses" (poses.txt), "poses" (EuRoC
  /// state_groundtruth_estimate0, preferred to the gyro), "gyro" (EuRoC imu0, bias included) or
  /// "" (none).
  std::string truth;

  bool hasPoses() const { return !orientations.empty(); }
  bool hasGyro() const { return !gyro.empty(); }
  /// Ground-truth frame-to-frame rotation R_{k-1}^T R_k (k >= 1), from poses or, for EuRoC without
  /// state_groundtruth_estimate0, from the gyro integrated between the two image stamps and rotated into the camera frame.
  /// Returns false when the sequence has neither (or the gyro does not cover the interval).
  /// The gyro's bias is NOT removed: EuRoC's ADIS16448 reads ~0.08 rad/s while standing still,
  /// so a static EuRoC stretch shows ~0.2 deg of "true" rotation per 50 ms frame.
  bool trueRotation(size_t k, Eigen::Matrix3d* rotation) const;
  /// Mean angular velocity between stamps of images k-1 and k, in the camera frame [rad/s]: the
  /// poses' rotation vector / dt when poses exist, else the gyro's mean rate.
  bool trueAngularVelocity(size_t k, Eigen::Vector3d* omega) const;
};

/// Loads a folder in the KITTI odometry layout (image_l/ or image_0/, calib.txt, optional
/// poses.txt and times.txt; 10 Hz assumed without times.txt) or the EuRoC ASL layout (cam0/,
/// optional imu0/ and state_groundtruth_estimate0/). Throws std::runtime_error naming the missing or malformed file.
Sequence loadSequence(const std::string& folder);

}  // namespace visual_gyro
