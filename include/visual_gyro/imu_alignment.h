// Aligning the visual gyro with a real IMU: the time offset between the two clocks, the camera's
// rotation in the IMU frame, the gyro's bias (and optionally its per-axis scale), estimated from
// the visual rates of a recording and the IMU's samples. ROS-free (Eigen only); `calibrate_imu`
// and `evaluate` (gyro truth) both use it. Method, outputs and observability: doc/imu_alignment.md.
//
// Conventions: stamps in seconds; t_imu = t_camera + time_offset (the IMU sample that belongs to a
// camera instant t carries the stamp t + time_offset). imu_from_camera maps camera-frame vectors
// into the IMU frame: omega_imu = imu_from_camera * omega_camera (the rotation of the camera
// frame in the IMU frame, as EuRoC's T_BS and a static tf imu -> camera). The gyro model is
// measured = diag(scale) * omega_imu + bias (+ white noise), in the IMU frame.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "visual_gyro/sequence.h"
#include "visual_gyro/visual_gyro.h"

namespace visual_gyro {

/// One frame interval of the visual gyro: the mean angular velocity between two images.
struct VisualRate {
  double start = 0.0;  ///< the previous image's stamp [s], camera clock
  double end = 0.0;    ///< this image's stamp [s], camera clock
  /// The estimator called the frame valid (FrameResult::hasEstimate); only valid frames are used.
  bool valid = false;
  Eigen::Vector3d rate = Eigen::Vector3d::Zero();  ///< rotation vector / (end - start) [rad/s], camera frame
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();  ///< of `rate` [(rad/s)^2], camera frame
};

/// The frame interval of a pipeline result for the image stamped `stamp` [s]: false (and *rate
/// untouched) when the frame has no interval (first frame, or skipped); an interval without an
/// estimate (frozen image, too few matches, ...) is returned with valid = false.
bool visualRateOf(const FrameResult& result, double stamp, VisualRate* rate);

/// Bad input to the alignment (no IMU, IMU stamps not increasing or not overlapping the images,
/// an IMU too slow for the frame rate, too few valid frames): the message says which.
struct ImuAlignmentError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// How the alignment searches and when it calls something observable.
struct ImuAlignmentSettings {
  double max_offset = 0.25;  ///< [s] offsets searched in [-max_offset, max_offset]
  bool estimate_scale = false;  ///< also estimate the gyro's per-axis scale
  /// When set, imu_from_camera is taken as known (e.g. EuRoC's T_BS) and not estimated.
  bool rotation_known = false;
  Eigen::Matrix3d known_imu_from_camera = Eigen::Matrix3d::Identity();
  /// Huber threshold on a frame's residual, in robust standard deviations of its Mahalanobis
  /// length (beyond it a frame's weight falls as 1 / length).
  double huber_threshold = 2.5;
  /// The camera "saw rotation" when its rates explain at least this fraction of the IMU's rate
  /// variation (1 - cost of the fit / cost of a bias alone); below, offset and rotation are not
  /// observable.
  double min_explained = 0.5;
  double max_offset_sigma = 0.002;   ///< [s] a less certain offset is reported not observable
  double max_rotation_sigma_deg = 1.0;  ///< [deg] per axis; a less certain axis is not observable
  int min_frames = 10;  ///< fewer valid frames covered by the IMU: an error
  /// The IMU must sample at least this many times per frame interval (median intervals).
  double min_samples_per_frame = 2.0;
};

/// How much of the camera-IMU rotation the motion determines.
enum class RotationObservability {
  kFull,      ///< rotation about at least two independent axes: the whole rotation
  kAxisOnly,  ///< rotation about one axis only: where that axis lies in the IMU frame, not the angle about it
  kNone,      ///< no rotation seen
  kKnown,     ///< given (ImuAlignmentSettings::rotation_known), not estimated
};

/// "full", "axis_only", "none" or "known".
const char* rotationObservabilityName(RotationObservability observability);

/// What the alignment found. Uncertainties are one standard deviation, from the fit's information
/// matrix (rotation, bias, scale) and the offset cost's curvature, both scaled by the fit's
/// reduced chi-square (so they do not rely on the covariances' absolute size).
struct ImuAlignment {
  int frames = 0;         ///< frame intervals given
  int frames_valid = 0;   ///< of them, valid estimates
  int frames_used = 0;    ///< valid, with the IMU covering them at every searched offset
  int imu_samples = 0;
  double imu_rate_hz = 0.0;       ///< from the median sample interval
  double gyro_noise = 0.0;        ///< per-sample white noise of the gyro [rad/s] (second differences)
  /// Fraction of the IMU's rate variation (about the bias) that the rotated visual rates explain.
  double explained = 0.0;
  bool motion = false;  ///< explained >= min_explained: the camera saw rotation

  bool offset_observable = false;
  double time_offset = 0.0;        ///< [s] t_imu = t_camera + time_offset (0 when not observable)
  double time_offset_sigma = 0.0;  ///< [s]

  RotationObservability rotation = RotationObservability::kNone;
  /// The fitted rotation (IMU <- camera). Meaningful as a whole only for kFull (and kKnown); for
  /// kAxisOnly it maps rotation_axis_camera onto rotation_axis_imu and nothing more.
  Eigen::Quaterniond imu_from_camera = Eigen::Quaterniond::Identity();
  /// Standard deviation of the rotation [deg] about its least certain axis (IMU frame).
  double rotation_sigma_deg = 0.0;
  /// kAxisOnly: the axis the camera rotated about (unit, camera frame) and the same axis in the
  /// IMU frame; zero otherwise.
  Eigen::Vector3d rotation_axis_camera = Eigen::Vector3d::Zero();
  Eigen::Vector3d rotation_axis_imu = Eigen::Vector3d::Zero();

  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();        ///< [rad/s], IMU frame
  Eigen::Vector3d gyro_bias_sigma = Eigen::Vector3d::Zero();  ///< [rad/s]
  bool has_scale = false;                                     ///< settings.estimate_scale
  Eigen::Vector3d gyro_scale = Eigen::Vector3d::Ones();       ///< measured / true rate, per IMU axis
  Eigen::Vector3d gyro_scale_sigma = Eigen::Vector3d::Zero();
  /// RMS over the used frames of |aligned, de-biased IMU mean rate - rotated visual rate| [rad/s].
  double rate_rmse = 0.0;
  /// What is not observable and why, one sentence each (empty when everything is).
  std::vector<std::string> notes;
};

/// Checks the IMU samples against the camera's frame stamps before any image is processed: throws
/// ImuAlignmentError when there are fewer than two samples, a stamp or rate is not finite, the
/// stamps do not increase, the IMU samples fewer than settings.min_samples_per_frame times per
/// frame interval, or its span does not overlap the frames' span.
void checkImuSamples(const std::vector<GyroSample>& imu, const std::vector<double>& frame_stamps,
                     const ImuAlignmentSettings& settings);

/// Estimates offset, rotation, bias (and scale) from the visual rates and the IMU samples: only
/// valid frames, each weighted by its covariance plus the IMU's noise over its interval, Huber
/// reweighted. Throws ImuAlignmentError for bad input (see checkImuSamples; also fewer than
/// settings.min_frames valid frames inside the IMU's span, or settings out of range). What the
/// motion does not determine is reported, not guessed (ImuAlignment::notes).
ImuAlignment alignImu(const std::vector<VisualRate>& rates, const std::vector<GyroSample>& imu,
                      const ImuAlignmentSettings& settings);

/// The IMU samples corrected by `alignment`: stamps moved onto the camera clock (t - time_offset,
/// 0 when not observable), the bias removed and the scale divided out, still in the IMU frame.
std::vector<GyroSample> alignedGyro(const std::vector<GyroSample>& imu, const ImuAlignment& alignment);

}  // namespace visual_gyro
