// Estimation methods behind one interface, so that `evaluate` runs ours and the baselines on the
// same frame pairs: each runner keeps its own state across frames (prior, previous estimate).
#pragma once

#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "baselines.h"
#include "frame_pairs.h"
#include "visual_gyro/backend.h"
#include "visual_gyro/rotation_estimator.h"
#include "visual_gyro/visual_gyro.h"

namespace visual_gyro {
namespace eval {

/// One method's estimate for one frame pair.
struct MethodEstimate {
  bool valid = false;
  /// kValid when valid; otherwise why not: the estimator's status (vote, paper), the baseline's
  /// (BaselineResult::status), or the pipeline's rules (the pair's image status for a frozen or
  /// textureless image, kImplausibleRate). Callers decide by this.
  FrameStatus status = FrameStatus::kNotEstimated;
  /// Why not valid, for people: the status name and reason (a baseline's own text); "" when
  /// valid.
  std::string error;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  ///< b_prev ~ R b_cur; identity when invalid
  Eigen::Vector3d rotation_vector = Eigen::Vector3d::Zero();
  double estimate_ms = 0.0;
  /// Covariance of the rotation vector [rad^2] (vote / paper; the baselines give none).
  bool has_covariance = false;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  int inliers = -1;  ///< vote / paper: RotationResult::inliers; -1 for the baselines
  bool pure_rotation = false;
  /// vote: RotationResult::translation (unit, previous camera frame; zero for a pure rotation or
  /// an invalid estimate); zero for the other methods.
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  VoteDiagnostics diagnostics;  ///< vote only
  /// vote: the calibration check's correlation of the estimate's residuals between neighbouring
  /// matches (FrameResult::residual_correlation); NaN for the other methods.
  double residual_correlation = std::numeric_limits<double>::quiet_NaN();
  // vote / paper only (NaN for the baselines): the estimate's voter part (host clock), its GPU
  // kernels (NaN on the CPU backend), and the host part after the vote (see EstimateTimes).
  double vote_ms = std::numeric_limits<double>::quiet_NaN();
  double vote_device_ms = std::numeric_limits<double>::quiet_NaN();
  double refine_ms = std::numeric_limits<double>::quiet_NaN();
};

/// One method with its own state across frames.
class MethodRunner {
 public:
  virtual ~MethodRunner() = default;
  /// Estimates the pair's rotation.
  virtual MethodEstimate run(const FramePair& pair) = 0;
  /// The backend that votes its estimates (kCpu for the baselines).
  virtual Backend backend() const = 0;
};

/// True for the package's own methods (vote, paper, and vote without one part:
/// `vote-without-<part>[+<part>...]`, VotePart); the others are baselines.
bool isOwnMethod(const std::string& method);
/// Every method this build has: vote, paper, then the compiled baselines.
std::vector<std::string> methodNames();
/// vote-without-<part> for every VotePart: the vote method with that part switched off.
std::vector<std::string> ablationMethodNames();
/// "" when this build has `method`, else why not (unknown, or needs OpenGV).
std::string methodProblem(const std::string& method);

/// The runner of `method` (isOwnMethod: a RotationEstimator with `estimator`'s settings and this
/// method, told whether the matches' positions are refined (RotationEstimator::setRefinedPositions)
/// and the angle their descriptor patch spans [rad] (RotationEstimator::setMatchFootprint,
/// matchFootprint() of the sequence's camera); else the baseline), wrapped so that it follows the
/// pipeline's plausibility rules (no estimate on a frozen or textureless image; a rate above
/// max_rate_dps is invalid; vote: the covariance inflated while the calibration does not fit,
/// judged from the matches' bearings with `pixel_angle_rad` radians per pixel) exactly as
/// VisualGyro does.
std::unique_ptr<MethodRunner> makeRunner(const std::string& method, const VisualGyroSettings& settings,
                                         const BaselineSettings& baseline, bool refined_positions,
                                         double match_footprint, double pixel_angle_rad);

}  // namespace eval
}  // namespace visual_gyro
