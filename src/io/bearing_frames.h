// Frames of matched bearing vectors for the CUDA voter's check and benchmark, and a synthetic
// generator so that both run without exported files. Header-only, plain C++ (also used by
// test/test_cuda_voter.cpp in the package build).
//
// Conventions as in hypothesis_math.h: unit bearings in the optical frame (x right, y down,
// z forward); b_prev ~ R b_cur with R = Ry(yaw) Rx(pitch) Rz(roll).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "hypothesis_math.h"
#include "visual_gyro/random.h"

namespace visual_gyro {
namespace bearings {

/// One frame pair's matches: prev[i] (frame k-1) <-> cur[i] (frame k), unit vectors.
struct BearingFrame {
  int64_t index = 0;  ///< frame number k in its sequence
  std::vector<hyp::Vec3f> prev;
  std::vector<hyp::Vec3f> cur;
  double dt = 0.0;         ///< time between the two images [s]; 0 when unknown (v1 files)
  bool has_truth = false;  ///< whether `truth` holds the true rotation
  /// True rotation, row-major, b_prev ~ R b_cur (R = R_{k-1}^T R_k); identity without truth.
  double truth[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
};

/// Settings of a synthetic frame: a random rotation, points at random depths, optional forward
/// translation (parallax), bearing noise and outlier matches.
struct SyntheticOptions {
  uint32_t matches = 2000;
  double outlier_ratio = 0.3;        ///< fraction of matches whose prev bearing is random
  double max_yaw_deg = 5.0;          ///< yaw uniform in [-max, max]
  double max_pitch_roll_deg = 1.0;   ///< pitch and roll uniform in [-max, max]
  double noise_deg = 0.02;           ///< std. dev. of the prev bearing's angular noise
  double forward_translation = 0.0;  ///< camera k's position in k-1 along +z [m]; depths 5..50 m
  double fov_x_deg = 90.0;           ///< horizontal field of view
  double fov_y_deg = 60.0;           ///< vertical field of view
};

/// Row-major R = Ry(yaw) Rx(pitch) Rz(roll) [rad] in double.
inline void rotationFromYawPitchRoll(double yaw, double pitch, double roll, double R[9]) {
  const double cy = std::cos(yaw), sy = std::sin(yaw), cp = std::cos(pitch), sp = std::sin(pitch);
  const double cr = std::cos(roll), sr = std::sin(roll);
  const double Ry[9] = {cy, 0, sy, 0, 1, 0, -sy, 0, cy};
  const double Rx[9] = {1, 0, 0, 0, cp, -sp, 0, sp, cp};
  const double Rz[9] = {cr, -sr, 0, sr, cr, 0, 0, 0, 1};
  double T[9];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      T[3 * r + c] = 0;
      for (int k = 0; k < 3; ++k) T[3 * r + c] += Rx[3 * r + k] * Rz[3 * k + c];
    }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      R[3 * r + c] = 0;
      for (int k = 0; k < 3; ++k) R[3 * r + c] += Ry[3 * r + k] * T[3 * k + c];
    }
}

/// A synthetic frame; deterministic in (options, seed). *truth_ypr (optional) receives the true
/// (yaw, pitch, roll) [rad].
inline BearingFrame makeSyntheticFrame(const SyntheticOptions& options, uint64_t seed, int64_t index = 0,
                                       double truth_ypr[3] = nullptr) {
  SplitMix64 rng(seed * 0x9E3779B97F4A7C15ull + 12345u);
  auto unit = [](SplitMix64& r) { return r.uniform(-1.0, 1.0); };
  auto gauss = [](SplitMix64& r) { return r.normal(); };
  const double deg = 3.14159265358979323846 / 180.0;
  const double yaw = options.max_yaw_deg * deg * unit(rng);
  const double pitch = options.max_pitch_roll_deg * deg * unit(rng);
  const double roll = options.max_pitch_roll_deg * deg * unit(rng);
  if (truth_ypr != nullptr) {
    truth_ypr[0] = yaw;
    truth_ypr[1] = pitch;
    truth_ypr[2] = roll;
  }
  double R[9];
  rotationFromYawPitchRoll(yaw, pitch, roll, R);
  const double tx = std::tan(0.5 * options.fov_x_deg * deg), ty = std::tan(0.5 * options.fov_y_deg * deg);
  auto randomBearing = [&](double out[3]) {
    const double x = tx * unit(rng), y = ty * unit(rng);
    const double len = std::sqrt(x * x + y * y + 1.0);
    out[0] = x / len;
    out[1] = y / len;
    out[2] = 1.0 / len;
  };
  auto toVec = [](const double v[3]) {
    const double len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    return hyp::make3(static_cast<float>(v[0] / len), static_cast<float>(v[1] / len), static_cast<float>(v[2] / len));
  };
  BearingFrame frame;
  frame.index = index;
  frame.dt = 0.1;
  frame.has_truth = true;
  std::copy(R, R + 9, frame.truth);
  frame.prev.reserve(options.matches);
  frame.cur.reserve(options.matches);
  for (uint32_t i = 0; i < options.matches; ++i) {
    double c[3], p[3];
    randomBearing(c);
    const double depth = 5.0 + 45.0 * 0.5 * (unit(rng) + 1.0);
    // X_prev = R X_cur + t, t = (0, 0, forward_translation): the point seen from camera k-1.
    for (int r = 0; r < 3; ++r) p[r] = depth * (R[3 * r] * c[0] + R[3 * r + 1] * c[1] + R[3 * r + 2] * c[2]);
    p[2] += options.forward_translation;
    const double len = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    for (double& v : p) v /= len;
    for (double& v : p) v += options.noise_deg * deg * gauss(rng);
    if (0.5 * (unit(rng) + 1.0) < options.outlier_ratio) randomBearing(p);
    frame.prev.push_back(toVec(p));
    frame.cur.push_back(toVec(c));
  }
  return frame;
}

/// `count` matches drawn from `frame` (a random subset, or the matches repeated with a tiny jitter
/// of 1e-5 rad when more are asked than exist), for timing at a given match count.
inline BearingFrame resampleFrame(const BearingFrame& frame, uint32_t count, uint64_t seed) {
  BearingFrame out;
  out.index = frame.index;
  out.dt = frame.dt;
  out.has_truth = frame.has_truth;
  std::copy(frame.truth, frame.truth + 9, out.truth);
  const size_t n = frame.prev.size();
  if (n == 0) return out;
  SplitMix64 rng(seed);
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  rng.shuffle(order);
  auto jitter = [](SplitMix64& r) { return static_cast<float>(1e-5 * r.normal()); };
  auto jittered = [&](hyp::Vec3f v) {
    v = hyp::make3(v.x + jitter(rng), v.y + jitter(rng), v.z + jitter(rng));
    return (1.f / hyp::norm(v)) * v;
  };
  for (uint32_t i = 0; i < count; ++i) {
    const size_t k = order[i % n];
    if (i < n) {
      out.prev.push_back(frame.prev[k]);
      out.cur.push_back(frame.cur[k]);
    } else {
      out.prev.push_back(jittered(frame.prev[k]));
      out.cur.push_back(jittered(frame.cur[k]));
    }
  }
  return out;
}

}  // namespace bearings
}  // namespace visual_gyro
