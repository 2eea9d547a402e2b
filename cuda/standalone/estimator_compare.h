// The whole estimator (voter plus host refinement) run over the frames of a bearing file on one
// backend, its figures against the file's truth, and the rule that judges a CUDA run against the
// CPU run: the CUDA backend must give the CPU backend's figures within 5 %. Header-only;
// needs Eigen and the core's rotation_estimator.cpp / rotation_refinement.cpp (used by the
// stand-alone tool cuda_estimator_check and by test/test_cuda_voter.cpp).
//
// Conventions as in rotation_estimator.h: b_prev ~ R b_cur, R = Ry(yaw) Rx(pitch) Rz(roll);
// errors are per frame pair, in degrees.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "bearing_frames.h"
#include "visual_gyro/rotation_estimator.h"

namespace visual_gyro {
namespace bearings {

/// Frames without a dt (version 1 files) are taken as 10 Hz.
constexpr double kDefaultFrameInterval = 0.1;

/// One backend's run of the estimator over a sequence of frames.
struct EstimatorRun {
  std::string backend;  ///< backend that voted ("cpu" or "cuda")
  int frames = 0;
  int invalid = 0;      ///< invalid estimates (counted as identity in the errors, as evaluate does)
  int with_truth = 0;   ///< frames with a true rotation
  double rot_rmse_deg = std::numeric_limits<double>::quiet_NaN();  ///< angle of R_est^T R_true
  double rot_max_deg = std::numeric_limits<double>::quiet_NaN();
  double yaw_rmse_deg = std::numeric_limits<double>::quiet_NaN();
  double mean_rate_dps = 0.0;  ///< mean |rotation vector| / dt [deg/s]
  std::vector<Eigen::Matrix3d> rotations;  ///< per frame (identity when invalid)
  std::vector<char> valid;
  /// Per-frame times [ms]: whole estimate, voter call, its GPU kernels, host part after the vote.
  std::vector<double> estimate_ms, vote_ms, vote_device_ms, refine_ms;
};

inline Eigen::Matrix3d truthOf(const BearingFrame& frame) {
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R(r, c) = frame.truth[3 * r + c];
  return R;
}

/// Runs `estimator` over `frames` in order, with the previous valid rotation as the prior (as the
/// pipeline and evaluate do).
inline EstimatorRun runEstimator(RotationEstimator* estimator, const std::vector<BearingFrame>& frames) {
  EstimatorRun run;
  run.backend = estimator->backendName();
  PriorTracker prior;
  double rot_sq = 0.0, yaw_sq = 0.0, rot_max = 0.0, rate_sum = 0.0;
  std::vector<Eigen::Vector3d> prev, cur;
  for (const BearingFrame& frame : frames) {
    const double dt = frame.dt > 0.0 ? frame.dt : kDefaultFrameInterval;
    prev.clear();
    cur.clear();
    for (size_t i = 0; i < frame.prev.size(); ++i) {
      prev.emplace_back(frame.prev[i].x, frame.prev[i].y, frame.prev[i].z);
      cur.emplace_back(frame.cur[i].x, frame.cur[i].y, frame.cur[i].z);
    }
    const RotationResult r = estimator->estimate(prev, cur, prior.priorFor(dt));
    prior.update(r, dt);
    const Eigen::Matrix3d R = r.valid() ? r.rotation : Eigen::Matrix3d::Identity();
    run.rotations.push_back(R);
    run.valid.push_back(r.valid() ? 1 : 0);
    run.invalid += r.valid() ? 0 : 1;
    run.estimate_ms.push_back(r.times.estimate);
    run.vote_ms.push_back(r.times.vote);
    run.vote_device_ms.push_back(r.times.vote_device);
    run.refine_ms.push_back(r.times.refine);
    rate_sum += Eigen::AngleAxisd(R).angle() / dt;
    if (frame.has_truth) {
      const Eigen::Matrix3d truth = truthOf(frame);
      const double rot_err = rotationAngleBetween(R, truth) * 180.0 / M_PI;
      double yaw_err = (yawPitchRollFromRotation(R)[0] - yawPitchRollFromRotation(truth)[0]) * kRadToDeg;
      yaw_err = std::remainder(yaw_err, 360.0);
      rot_sq += rot_err * rot_err;
      yaw_sq += yaw_err * yaw_err;
      rot_max = std::max(rot_max, rot_err);
      ++run.with_truth;
    }
    ++run.frames;
  }
  if (run.frames > 0) run.mean_rate_dps = rate_sum / run.frames * 180.0 / M_PI;
  if (run.with_truth > 0) {
    run.rot_rmse_deg = std::sqrt(rot_sq / run.with_truth);
    run.yaw_rmse_deg = std::sqrt(yaw_sq / run.with_truth);
    run.rot_max_deg = rot_max;
  }
  return run;
}

/// Median of per-frame values (NaN for none).
inline double medianOf(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

/// The verdict on a second run (CUDA) against a reference run (CPU) over the same frames.
struct EstimatorComparison {
  std::vector<std::string> problems;  ///< empty when the runs agree
  double max_rotation_difference_deg = 0.0;  ///< largest per-frame angle between the two results
  int validity_differs = 0;                  ///< frames valid in one run only
  bool passed() const { return problems.empty(); }
};

/// The runs agree when they cover the same frames, have as many invalid estimates, and their
/// figures (rotation RMSE and max, yaw RMSE, mean rate) differ by at most `relative` of the
/// reference plus `absolute` (deg or deg/s: figures near zero cannot meet a relative bound alone).
/// Per-frame differences are reported, not judged: the two backends' votes differ by float
/// rounding at bin edges, which may move a frame's start within the refinement's basin.
inline EstimatorComparison compareEstimatorRuns(const EstimatorRun& reference, const EstimatorRun& other,
                                                double relative = 0.05, double absolute = 1e-3) {
  EstimatorComparison c;
  if (reference.frames != other.frames) {
    c.problems.push_back("frames " + std::to_string(other.frames) + " vs " + std::to_string(reference.frames));
    return c;
  }
  for (int f = 0; f < reference.frames; ++f) {
    c.max_rotation_difference_deg = std::max(
        c.max_rotation_difference_deg,
        rotationAngleBetween(reference.rotations[f], other.rotations[f]) * 180.0 / M_PI);
    c.validity_differs += reference.valid[f] != other.valid[f];
  }
  if (reference.invalid != other.invalid)
    c.problems.push_back("invalid estimates " + std::to_string(other.invalid) + " vs " +
                         std::to_string(reference.invalid));
  auto check = [&](const char* name, double ref, double value) {
    if (std::isnan(ref) && std::isnan(value)) return;
    if (!(std::fabs(value - ref) <= relative * std::fabs(ref) + absolute))
      c.problems.push_back(std::string(name) + " " + std::to_string(value) + " vs " + std::to_string(ref));
  };
  check("rot_rmse_deg", reference.rot_rmse_deg, other.rot_rmse_deg);
  check("rot_max_deg", reference.rot_max_deg, other.rot_max_deg);
  check("yaw_rmse_deg", reference.yaw_rmse_deg, other.yaw_rmse_deg);
  check("mean_rate_dps", reference.mean_rate_dps, other.mean_rate_dps);
  return c;
}

}  // namespace bearings
}  // namespace visual_gyro
