// Settings shared by cuda_voter_check and cuda_voter_bench: the two vote grids and the CUDA
// voter's availability. Plain C++ (command lines: src/tools/command_line.h).
#pragma once

#include <chrono>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <string>

#include "cuda_voter.h"
#include "hypothesis_voter.h"

namespace visual_gyro {
namespace bearings {

constexpr double kRadPerDeg = 3.14159265358979323846 / 180.0;

/// The two grids every check and benchmark runs, as the estimator's methods use them.
enum class GridKind { kYaw, kRotation };

inline const char* gridName(GridKind kind) { return kind == GridKind::kYaw ? "yaw" : "rotation"; }

/// A VoteRequest for `frame`-style bearings on one of the two standard grids:
///  - yaw (the paper): bin 0.1 deg, window +-15 deg (300 bins), centroid subtraction on;
///  - rotation (method vote): rotation-vector cells of 0.5 deg, 24 bins per axis (+-6 deg around
///    zero), centroid subtraction off, max_angle_change 0.5 deg.
/// Both: min separation 0.3 deg, min triangle area 0.5 deg^2.
inline VoteRequest makeRequest(GridKind kind, const hyp::Vec3f* prev, const hyp::Vec3f* cur, uint32_t matches,
                               uint32_t hypotheses, uint64_t seed) {
  VoteRequest q;
  q.prev = prev;
  q.cur = cur;
  q.matches = matches;
  q.hypotheses = hypotheses;
  q.seed = seed;
  q.triple.min_separation = static_cast<float>(0.3 * kRadPerDeg);
  q.triple.min_triangle_area = static_cast<float>(0.5 * kRadPerDeg * kRadPerDeg);
  if (kind == GridKind::kYaw) {
    q.triple.centroid_subtraction = 1;
    q.triple.max_angle_change = 0.f;
    q.grid.kind = hyp::kVoteYaw;
    q.grid.bin_width = static_cast<float>(0.1 * kRadPerDeg);
    q.grid.bins = 300;
  } else {
    q.triple.centroid_subtraction = 0;
    q.triple.max_angle_change = static_cast<float>(0.5 * kRadPerDeg);
    q.grid.kind = hyp::kVoteRotationVector;
    q.grid.bin_width = static_cast<float>(0.5 * kRadPerDeg);
    q.grid.bins = 24;
  }
  q.grid.centre[0] = q.grid.centre[1] = q.grid.centre[2] = 0.f;
  return q;
}

/// The CUDA voter, or null with the reason in *why when no device works.
inline std::unique_ptr<HypothesisVoter> tryCudaVoter(int device, std::string* why) {
  if (!cudaDeviceAvailable(why, device)) return nullptr;
  try {
    return createCudaVoter(device);
  } catch (const std::exception& e) {
    *why = e.what();
    return nullptr;
  }
}

/// Milliseconds since `start` on the host's steady clock.
inline double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace bearings
}  // namespace visual_gyro
