// The accuracy metrics, defined once: per-frame rotation and yaw errors, rate errors and NEES, and
// their summaries (RMSE, max, means). Used by `evaluate`, the ROS summaries (bag_tools) and the
// CUDA estimator check. Eigen only (no OpenCV, no ROS).
//
// Scoring rule: an invalid estimate counts as the identity (no rotation, zero rate): that is what a
// consumer integrating the output would get. Errors in degrees, rates in degrees per second.
#pragma once

#include <limits>

#include <Eigen/Core>

namespace visual_gyro {

class JsonObject;

namespace metrics {

/// 99 % quantile of the chi-square distribution with 3 degrees of freedom.
constexpr double kChiSquare3Dof99 = 11.345;
/// 99.9 % quantile of the chi-square distribution with 3 degrees of freedom.
constexpr double kChiSquare3Dof999 = 16.266;
/// A covariance is over-confident on a run when its NEES mean exceeds this (an honest one averages
/// 3, the degrees of freedom; the truth's own errors and a covariance floor move it by a factor of
/// about two either way)...
constexpr double kHonestNeesMeanMax = 6.0;
/// ...or when more than this share of its frames lie beyond kChiSquare3Dof99 (1 % would be exact).
constexpr double kHonestBeyond99Max = 0.05;

/// One frame's estimate. R maps current-frame bearings into the previous frame (b_prev ~ R b_cur).
struct FrameEstimate {
  bool valid = false;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  ///< ignored when !valid
  double dt = 0.0;                                         ///< [s], > 0 for a rate
  /// Covariance of the rotation vector [rad^2], camera frame; used for NEES when has_covariance.
  bool has_covariance = false;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
};

/// One frame's reference.
struct FrameTruth {
  bool has_rotation = false;
  /// The rotation comes from poses (not a biased gyro): only then does it judge a covariance.
  bool from_poses = false;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  /// Standard deviation [rad] of the truth's own rotation error about the camera's x, y and z axes:
  /// NEES judges the estimate's covariance plus diag(sigma^2), since the error it sees is the
  /// estimate's and the truth's.
  Eigen::Vector3d sigma_rad = Eigen::Vector3d::Zero();
  bool has_rate = false;
  Eigen::Vector3d rate = Eigen::Vector3d::Zero();  ///< mean angular velocity, camera frame [rad/s]
};

/// A frame's errors. NaN where the reference is missing.
struct FrameErrors {
  Eigen::Matrix3d scored_rotation = Eigen::Matrix3d::Identity();  ///< identity when invalid
  double yaw_deg = 0.0;        ///< yaw of the scored rotation
  double rate_dps = 0.0;       ///< |rotation vector| / dt of the scored rotation
  double true_yaw_deg = std::numeric_limits<double>::quiet_NaN();
  double rotation_error_deg = std::numeric_limits<double>::quiet_NaN();  ///< angle of R_est^T R_true
  double yaw_error_deg = std::numeric_limits<double>::quiet_NaN();       ///< signed, wrapped to (-180, 180]
  /// Rotation vector of R_est^T R_true, camera frame [deg].
  Eigen::Vector3d error_vector_deg = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  double rate_error_dps = std::numeric_limits<double>::quiet_NaN();  ///< |omega_est - omega_true|
  /// e^T C^-1 e of the rotation-vector error (valid estimates with a covariance against pose truth).
  double nees = std::numeric_limits<double>::quiet_NaN();
};

/// Scores one frame.
FrameErrors scoreFrame(const FrameEstimate& estimate, const FrameTruth& truth);

/// Summary over frames. NaN where no frame had the reference.
struct AccuracySummary {
  int frames = 0;
  int invalid = 0;
  int with_truth = 0;  ///< frames with a reference rotation
  int with_rate = 0;   ///< frames with a reference rate
  int with_nees = 0;   ///< frames whose NEES counts
  double rot_rmse_deg = std::numeric_limits<double>::quiet_NaN();
  double rot_max_deg = std::numeric_limits<double>::quiet_NaN();
  double yaw_rmse_deg = std::numeric_limits<double>::quiet_NaN();
  double yaw_max_deg = std::numeric_limits<double>::quiet_NaN();
  double mean_rate_dps = std::numeric_limits<double>::quiet_NaN();  ///< over all frames
  double rate_rmse_dps = std::numeric_limits<double>::quiet_NaN();
  double true_rate_mean_dps = std::numeric_limits<double>::quiet_NaN();  ///< mean |reference rate|
  double true_rotation_mean_deg = std::numeric_limits<double>::quiet_NaN();  ///< mean reference angle
  double nees_mean = std::numeric_limits<double>::quiet_NaN();
  double nees_beyond99 = std::numeric_limits<double>::quiet_NaN();  ///< fraction beyond kChiSquare3Dof99
};

/// Accumulates scored frames into an AccuracySummary.
class AccuracyAccumulator {
 public:
  /// Adds one frame (its estimate's validity, its errors and its reference).
  void add(bool valid, const FrameErrors& errors, const FrameTruth& truth);
  AccuracySummary summary() const;

 private:
  AccuracySummary counts_;
  double rot_sq_ = 0.0, rot_max_ = 0.0, yaw_sq_ = 0.0, yaw_max_ = 0.0, rate_sum_ = 0.0;
  double rate_sq_ = 0.0, true_rate_sum_ = 0.0, true_rot_sum_ = 0.0, nees_sum_ = 0.0;
  int nees_beyond_ = 0;
};

/// Adds the summary's figures to a JSON line under the keys every report uses: frames, invalid,
/// rot_rmse_deg, rot_max_deg, yaw_rmse_deg, yaw_max_deg, mean_rate_dps, rate_rmse_dps.
void addAccuracyFields(const AccuracySummary& summary, JsonObject* json);

}  // namespace metrics
}  // namespace visual_gyro
