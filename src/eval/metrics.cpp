#include "metrics.h"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>

#include "json_writer.h"
#include "visual_gyro/geometry.h"

namespace visual_gyro {
namespace metrics {

FrameErrors scoreFrame(const FrameEstimate& estimate, const FrameTruth& truth) {
  FrameErrors e;
  e.scored_rotation = estimate.valid ? estimate.rotation : Eigen::Matrix3d::Identity();
  const Eigen::Vector3d rotation_vector = so3Log(e.scored_rotation);
  e.yaw_deg = yawPitchRollFromRotation(e.scored_rotation)[0] * kRadToDeg;
  const Eigen::Vector3d omega = estimate.dt > 0.0 ? Eigen::Vector3d(rotation_vector / estimate.dt)
                                                  : Eigen::Vector3d::Zero();
  e.rate_dps = omega.norm() * kRadToDeg;
  if (truth.has_rotation) {
    const Eigen::Matrix3d error = e.scored_rotation.transpose() * truth.rotation;
    e.true_yaw_deg = yawPitchRollFromRotation(truth.rotation)[0] * kRadToDeg;
    e.rotation_error_deg = rotationAngle(error) * kRadToDeg;
    e.yaw_error_deg = wrapAngleDeg(e.yaw_deg - e.true_yaw_deg);
    // Error as a rotation vector in the camera frame, the frame of the covariance.
    const Eigen::Vector3d error_vector = so3Log(error);
    e.error_vector_deg = error_vector * kRadToDeg;
    if (truth.from_poses && estimate.valid && estimate.has_covariance) {
      Eigen::Matrix3d seen = estimate.covariance;
      seen.diagonal() += truth.sigma_rad.cwiseProduct(truth.sigma_rad);
      const Eigen::FullPivLU<Eigen::Matrix3d> lu(seen);
      if (lu.isInvertible()) e.nees = error_vector.dot(lu.solve(error_vector));
    }
  }
  if (truth.has_rate && estimate.dt > 0.0) e.rate_error_dps = (omega - truth.rate).norm() * kRadToDeg;
  return e;
}

void AccuracyAccumulator::add(bool valid, const FrameErrors& errors, const FrameTruth& truth) {
  ++counts_.frames;
  if (!valid) ++counts_.invalid;
  rate_sum_ += errors.rate_dps;
  if (std::isfinite(errors.rotation_error_deg)) {
    ++counts_.with_truth;
    rot_sq_ += errors.rotation_error_deg * errors.rotation_error_deg;
    rot_max_ = std::max(rot_max_, errors.rotation_error_deg);
    yaw_sq_ += errors.yaw_error_deg * errors.yaw_error_deg;
    yaw_max_ = std::max(yaw_max_, std::abs(errors.yaw_error_deg));
    true_rot_sum_ += rotationAngle(truth.rotation) * kRadToDeg;
  }
  if (std::isfinite(errors.rate_error_dps)) {
    ++counts_.with_rate;
    rate_sq_ += errors.rate_error_dps * errors.rate_error_dps;
    true_rate_sum_ += truth.rate.norm() * kRadToDeg;
  }
  if (std::isfinite(errors.nees)) {
    ++counts_.with_nees;
    nees_sum_ += errors.nees;
    nees_beyond_ += errors.nees > kChiSquare3Dof99;
  }
}

AccuracySummary AccuracyAccumulator::summary() const {
  AccuracySummary s = counts_;
  if (s.frames > 0) s.mean_rate_dps = rate_sum_ / s.frames;
  if (s.with_truth > 0) {
    s.rot_rmse_deg = std::sqrt(rot_sq_ / s.with_truth);
    s.rot_max_deg = rot_max_;
    s.yaw_rmse_deg = std::sqrt(yaw_sq_ / s.with_truth);
    s.yaw_max_deg = yaw_max_;
    s.true_rotation_mean_deg = true_rot_sum_ / s.with_truth;
  }
  if (s.with_rate > 0) {
    s.rate_rmse_dps = std::sqrt(rate_sq_ / s.with_rate);
    s.true_rate_mean_dps = true_rate_sum_ / s.with_rate;
  }
  if (s.with_nees > 0) {
    s.nees_mean = nees_sum_ / s.with_nees;
    s.nees_beyond99 = static_cast<double>(nees_beyond_) / s.with_nees;
  }
  return s;
}

void addAccuracyFields(const AccuracySummary& a, JsonObject* json) {
  json->add("frames", a.frames)
      .add("invalid", a.invalid)
      .add("rot_rmse_deg", a.rot_rmse_deg)
      .add("rot_max_deg", a.rot_max_deg)
      .add("yaw_rmse_deg", a.yaw_rmse_deg)
      .add("yaw_max_deg", a.yaw_max_deg)
      .add("mean_rate_dps", a.mean_rate_dps)
      .add("rate_rmse_dps", a.rate_rmse_dps);
}

}  // namespace metrics
}  // namespace visual_gyro
