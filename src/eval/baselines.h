// Baseline rotation estimators for the evaluation command: OpenCV's 5-point and 8-point RANSAC and,
// when compiled with VISUAL_GYRO_WITH_OPENGV, three OpenGV RANSAC problems. They all see the same
// matched bearings as the project's own estimators.
//
// Convention (as in rotation_estimator.h): every baseline returns R with b_prev ~ R b_cur, i.e. the
// rotation mapping current-frame bearings into the previous frame. Angles in radians.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "visual_gyro/frame_status.h"

namespace visual_gyro {
namespace eval {

/// Result of one baseline estimate.
struct BaselineResult {
  bool valid = false;   ///< false: no usable model (see error); rotation is then identity
  /// kValid when valid; else the nearest frame status: kBadBearings (lists of unequal length,
  /// unusable bearings), kTooFewMatches, kDegenerate (no model, or no rotation from it),
  /// kTooFewInliers (fewer than min_inliers), kEstimatorFailed (the library threw).
  FrameStatus status = FrameStatus::kNotEstimated;
  std::string error;    ///< why not valid, for people
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  ///< b_prev ~ R b_cur
  int inliers = 0;      ///< inliers of the final model
};

/// Settings shared by the baselines.
struct BaselineSettings {
  /// Inlier threshold as an angle [rad]; the evaluation uses 1 px / fx ("1 px-equivalent").
  double threshold_rad = 1.0 / 500.0;
  double confidence = 0.999;  ///< RANSAC success probability
  int max_iterations = 1000;  ///< RANSAC iteration limit (OpenGV; OpenCV uses its own default)
  int min_inliers = 8;        ///< a model with fewer inliers is invalid
  uint64_t seed = 1;          ///< OpenGV eigensolver: seeds rand() so runs are reproducible
};

/// Names of the baselines compiled into this build, in a stable order.
std::vector<std::string> baselineNames();

/// True when `name` is a baseline compiled into this build.
bool isBaselineCompiled(const std::string& name);

/// True when `name` is a baseline that exists only with OpenGV (whether compiled or not).
bool isOpenGvBaseline(const std::string& name);

/// Runs the baseline `name` ("essential5", "fundamental8", "opengv_rotation_only",
/// "opengv_eigensolver", "opengv_5pt") on matched unit bearings previous[i] <-> current[i].
/// `initial` is the starting rotation of the eigensolver (identity or the previous estimate); the
/// others ignore it. Never throws for bad input (returns an invalid result); throws
/// std::invalid_argument for an unknown or not compiled-in name.
BaselineResult runBaseline(const std::string& name, const std::vector<Eigen::Vector3d>& previous,
                           const std::vector<Eigen::Vector3d>& current,
                           const BaselineSettings& settings,
                           const Eigen::Matrix3d& initial = Eigen::Matrix3d::Identity());

}  // namespace eval
}  // namespace visual_gyro
