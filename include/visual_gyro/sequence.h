// Reading image sequences with ground truth: the KITTI odometry layout and the EuRoC ASL layout.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "visual_gyro/camera_model.h"

namespace visual_gyro {

/// One gyro sample.
struct GyroSample {
  double stamp = 0.0;                                  ///< [s]
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  ///< [rad/s], IMU (body) frame
};

/// Error [deg] of KITTI's OXTS RT3003 poses on one frame-to-frame rotation about the camera's x
/// (pitch) and z (roll) axes: the device's specified roll and pitch accuracy.
constexpr double kKittiPosesTiltSigmaDeg = 0.03;
/// Error [deg] of KITTI's poses about the camera's y axis (heading): the device's specified
/// heading accuracy. On kitti_straight's first frames every part of the image agrees on a yaw
/// 0.10-0.15 deg from the poses' (doc/covariance.md).
constexpr double kKittiPosesHeadingSigmaDeg = 0.1;
/// Per-axis error [deg] of EuRoC's state_groundtruth_estimate0 on one 50 ms frame-to-frame
/// rotation: its orientation between laser-tracker fixes is the ADIS16448's integrated rate, whose
/// angle random walk (0.66 deg/sqrt(h)) gives 0.0025 deg in 50 ms.
constexpr double kEurocPosesSigmaDeg = 0.0025;
/// File of the KITTI layout that overrides the KITTI poses' error: one number [deg] for all three
/// camera axes or three (x, y, z). The renderer writes 0: its poses are exact.
constexpr const char* kTruthSigmaFile = "truth_sigma_deg.txt";

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
  /// Standard deviation [deg] of the ground truth's own error on one frame-to-frame rotation, about
  /// the camera's x, y and z axes: what the truth adds to an estimate's error, so the evaluation's
  /// NEES adds it to the estimate's covariance (the estimate cannot know it). KITTI layout:
  /// `truth_sigma_deg.txt` when present, else kKittiPosesTiltSigmaDeg about x and z and
  /// kKittiPosesHeadingSigmaDeg about y; EuRoC poses: kEurocPosesSigmaDeg; zero without pose truth.
  Eigen::Vector3d truth_sigma_deg = Eigen::Vector3d::Zero();
  /// Factor by which every image is downscaled as it is read (readImage); `camera` is already the
  /// downscaled one (scaleSequence). 1: the images as stored.
  double image_scale = 1.0;

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

/// Size [px] of a width x height image downscaled by `factor`, 0 < factor <= 1: each side
/// rounded to the nearest whole pixel, at least 1. Throws std::invalid_argument for a factor out
/// of range or a non-positive size.
cv::Size scaledImageSize(int width, int height, double factor);

/// `camera` for its images downscaled by `factor` (scaledImageSize). Each axis scales by the ratio
/// the rounded size realises, s = width' / width (height' / height for y), the one an area resize
/// to that size maps pixels with: fx' = s fx and, pixel centres at whole coordinates,
/// cx' = (cx + 0.5) s - 0.5 (likewise fy, cy). The distortion acts on normalised coordinates and
/// stays. Throws std::invalid_argument for a factor out of (0, 1].
CameraModel scaledCamera(const CameraModel& camera, double factor);

/// `image` downscaled by `factor` to scaledImageSize with area interpolation (each output pixel
/// the mean of the input area it covers, as a sensor with larger pixels would see it); a copy of
/// `image` for factor 1. Throws std::invalid_argument for an empty image or a factor out of range.
cv::Mat scaledImage(const cv::Mat& image, double factor);

/// Downscales a loaded sequence by `factor` (evaluate --scale): its camera becomes
/// scaledCamera(camera, factor) and readImage resizes every image alike. Throws
/// std::invalid_argument for a factor out of (0, 1] or a sequence already downscaled.
void scaleSequence(Sequence* sequence, double factor);

/// Image k of the sequence in grayscale, downscaled by its image_scale. Throws std::runtime_error
/// naming the file when it cannot be read.
cv::Mat readImage(const Sequence& sequence, size_t k);

/// Loads a folder in the KITTI odometry layout (image_l/ or image_0/, calib.txt, optional
/// poses.txt and times.txt; 10 Hz assumed without times.txt) or the EuRoC ASL layout (cam0/,
/// optional imu0/ and state_groundtruth_estimate0/). Throws std::runtime_error naming the missing or malformed file.
Sequence loadSequence(const std::string& folder);

}  // namespace visual_gyro
