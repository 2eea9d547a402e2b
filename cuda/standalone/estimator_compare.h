// The whole estimator (voter plus host refinement) run over the frames of a bearing file on one
// backend, its figures against the file's truth, and the rule that judges a CUDA run against the
// CPU run: the CUDA backend must give the CPU backend's figures within 5 %. Header-only;
// needs Eigen, the estimator and the metrics module (used by the stand-alone tool
// cuda_estimator_check and by test/test_bearing_tools.cpp).
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
#include "metrics.h"
#include "visual_gyro/rotation_estimator.h"

namespace visual_gyro {
namespace bearings {

/// Frames without a dt (version 1 files) are taken as 10 Hz.
constexpr double kDefaultFrameInterval = 0.1;

/// One backend's run of the estimator over a sequence of frames.
struct EstimatorRun {
  Backend backend = Backend::kCpu;  ///< backend that voted
  /// The figures, as evaluate computes them (invalid estimates count as identity).
  metrics::AccuracySummary accuracy;
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
/// pipeline and evaluate do), scored by the metrics module (invalid = identity, as evaluate does).
inline EstimatorRun runEstimator(RotationEstimator* estimator, const std::vector<BearingFrame>& frames) {
  EstimatorRun run;
  run.backend = estimator->backend();
  PriorTracker prior;
  metrics::AccuracyAccumulator accuracy;
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
    metrics::FrameEstimate scored;
    scored.valid = r.valid();
    scored.rotation = r.rotation;
    scored.dt = dt;
    metrics::FrameTruth truth;
    truth.has_rotation = frame.has_truth;
    if (frame.has_truth) truth.rotation = truthOf(frame);
    const metrics::FrameErrors errors = metrics::scoreFrame(scored, truth);
    accuracy.add(r.valid(), errors, truth);
    run.rotations.push_back(errors.scored_rotation);
    run.valid.push_back(r.valid() ? 1 : 0);
    run.estimate_ms.push_back(r.times.estimate);
    run.vote_ms.push_back(r.times.vote);
    run.vote_device_ms.push_back(r.times.vote_device);
    run.refine_ms.push_back(r.times.refine);
  }
  run.accuracy = accuracy.summary();
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
  if (reference.accuracy.frames != other.accuracy.frames) {
    c.problems.push_back("frames " + std::to_string(other.accuracy.frames) + " vs " + std::to_string(reference.accuracy.frames));
    return c;
  }
  for (int f = 0; f < reference.accuracy.frames; ++f) {
    c.max_rotation_difference_deg = std::max(
        c.max_rotation_difference_deg,
        rotationAngleBetween(reference.rotations[f], other.rotations[f]) * kRadToDeg);
    c.validity_differs += reference.valid[f] != other.valid[f];
  }
  if (reference.accuracy.invalid != other.accuracy.invalid)
    c.problems.push_back("invalid estimates " + std::to_string(other.accuracy.invalid) + " vs " +
                         std::to_string(reference.accuracy.invalid));
  auto check = [&](const char* name, double ref, double value) {
    if (std::isnan(ref) && std::isnan(value)) return;
    if (!(std::fabs(value - ref) <= relative * std::fabs(ref) + absolute))
      c.problems.push_back(std::string(name) + " " + std::to_string(value) + " vs " + std::to_string(ref));
  };
  check("rot_rmse_deg", reference.accuracy.rot_rmse_deg, other.accuracy.rot_rmse_deg);
  check("rot_max_deg", reference.accuracy.rot_max_deg, other.accuracy.rot_max_deg);
  check("yaw_rmse_deg", reference.accuracy.yaw_rmse_deg, other.accuracy.yaw_rmse_deg);
  check("mean_rate_dps", reference.accuracy.mean_rate_dps, other.accuracy.mean_rate_dps);
  return c;
}

}  // namespace bearings
}  // namespace visual_gyro
