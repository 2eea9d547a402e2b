// Hypothesis-level math shared verbatim by the CPU backend and the CUDA kernels.
//
// Everything here is plain C++ on POD types (no Eigen, no OpenCV, no CUDA headers), so the
// same code is compiled by g++ for the CPU backend and by nvcc for the device; given the same
// seed both draw the same triples and, up to floating-point rounding, cast the same votes.
//
// Conventions used throughout visual_gyro:
//  - Bearing vectors are unit 3-vectors in the camera's optical frame (x right, y down, z forward).
//  - The frame-to-frame rotation R maps bearings of the CURRENT frame k into the PREVIOUS frame
//    k-1: b_prev ~ R * b_cur (exact for pure rotation). R equals R_{k-1}^T R_k of camera poses
//    (the pose of camera k expressed in camera k-1), as in KITTI's poses.txt.
//  - Matrices are row-major, m[3 * row + col].
//  - Angles are radians.
#pragma once

#include <cmath>
#include <cstdint>

#if defined(__CUDACC__)
#define VG_HD __host__ __device__ __forceinline__
#else
#define VG_HD inline
#endif

namespace visual_gyro {
namespace hyp {

/// 3-vector of floats (a bearing, a rotation vector, ...).
struct Vec3f {
  float x, y, z;
};

/// Row-major 3x3 matrix of floats: m[3 * row + col].
struct Mat3f {
  float m[9];
};

VG_HD Vec3f make3(float x, float y, float z) { return Vec3f{x, y, z}; }
VG_HD Vec3f operator+(Vec3f a, Vec3f b) { return make3(a.x + b.x, a.y + b.y, a.z + b.z); }
VG_HD Vec3f operator-(Vec3f a, Vec3f b) { return make3(a.x - b.x, a.y - b.y, a.z - b.z); }
VG_HD Vec3f operator*(float s, Vec3f a) { return make3(s * a.x, s * a.y, s * a.z); }
VG_HD float dot(Vec3f a, Vec3f b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
VG_HD Vec3f cross(Vec3f a, Vec3f b) {
  return make3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
VG_HD float norm(Vec3f a) { return sqrtf(dot(a, a)); }

/// R * v for a row-major R.
VG_HD Vec3f mul(const Mat3f& R, Vec3f v) {
  return make3(R.m[0] * v.x + R.m[1] * v.y + R.m[2] * v.z, R.m[3] * v.x + R.m[4] * v.y + R.m[5] * v.z,
               R.m[6] * v.x + R.m[7] * v.y + R.m[8] * v.z);
}

// ---------------------------------------------------------------------------------------------
// Counter-based random numbers: Philox4x32-10 (Salmon et al., SC'11). Stateless, so hypothesis h
// of a frame is a pure function of (seed, h): any thread, on any device, draws the same triple.
// ---------------------------------------------------------------------------------------------

/// Philox4x32-10 block: 4 random 32-bit words for a 128-bit counter and a 64-bit key.
VG_HD void philox4x32(const uint32_t counter[4], uint32_t key_lo, uint32_t key_hi, uint32_t out[4]) {
  uint32_t c0 = counter[0], c1 = counter[1], c2 = counter[2], c3 = counter[3];
  uint32_t k0 = key_lo, k1 = key_hi;
  for (int round = 0; round < 10; ++round) {
    const uint64_t p0 = static_cast<uint64_t>(0xD2511F53u) * c0;
    const uint64_t p1 = static_cast<uint64_t>(0xCD9E8D57u) * c2;
    const uint32_t hi0 = static_cast<uint32_t>(p0 >> 32), lo0 = static_cast<uint32_t>(p0);
    const uint32_t hi1 = static_cast<uint32_t>(p1 >> 32), lo1 = static_cast<uint32_t>(p1);
    c0 = hi1 ^ c1 ^ k0;
    c1 = lo1;
    c2 = hi0 ^ c3 ^ k1;
    c3 = lo0;
    k0 += 0x9E3779B9u;
    k1 += 0xBB67AE85u;
  }
  out[0] = c0;
  out[1] = c1;
  out[2] = c2;
  out[3] = c3;
}

/// Uniform integer in [0, n) from a 32-bit word (multiply-high: no division, bias < n / 2^32).
VG_HD uint32_t scaleToRange(uint32_t word, uint32_t n) {
  return static_cast<uint32_t>((static_cast<uint64_t>(word) * n) >> 32);
}

/// Three distinct indices in [0, n) from three random words (drawTriple's second half).
VG_HD void drawFromWords(uint32_t r0, uint32_t r1, uint32_t r2, uint32_t n, uint32_t idx[3]) {
  // Sampling without replacement by skipping the indices already taken keeps the draw branch-light
  // and loop-free, which matters for warp divergence on the GPU.
  uint32_t a = scaleToRange(r0, n);
  uint32_t b = scaleToRange(r1, n - 1);
  if (b >= a) ++b;
  const uint32_t lo = a < b ? a : b;
  const uint32_t hi = a < b ? b : a;
  uint32_t c = scaleToRange(r2, n - 2);
  if (c >= lo) ++c;
  if (c >= hi) ++c;
  idx[0] = a;
  idx[1] = b;
  idx[2] = c;
}

/// Counter words of hypothesis h's Philox block (after the hypothesis index: "visu", "gyro").
constexpr uint32_t kTripleCounterWord2 = 0x76697375u, kTripleCounterWord3 = 0x6779726fu;

/// Draws three distinct match indices in [0, n) for hypothesis `hypothesis` of a frame.
/// Requires n >= 3. Deterministic in (seed, hypothesis, n).
VG_HD void drawTriple(uint64_t seed, uint32_t hypothesis, uint32_t n, uint32_t idx[3]) {
  const uint32_t counter[4] = {hypothesis, 0u, kTripleCounterWord2, kTripleCounterWord3};
  uint32_t r[4];
  philox4x32(counter, static_cast<uint32_t>(seed), static_cast<uint32_t>(seed >> 32), r);
  drawFromWords(r[0], r[1], r[2], n, idx);
}

// ---------------------------------------------------------------------------------------------
// Rotation from three correspondences: Arun, Huang & Blostein (1987), with the SVD done in
// registers by one-sided (Hestenes) Jacobi, which works on H itself rather than H^T H and so keeps
// the accuracy float needs for narrow-field-of-view bearings.
// ---------------------------------------------------------------------------------------------

/// Why a triple produced no vote.
enum TripleStatus : int32_t {
  kTripleOk = 0,
  kTripleRepeated = 1,       ///< two bearings closer than the minimum separation (either frame)
  kTripleCollinear = 2,      ///< the three bearings span too small a triangle
  kTripleReflection = 3,     ///< det(H) < 0: the best orthogonal fit is a reflection
  kTripleInconsistent = 4,   ///< pairwise angles differ between frames (cannot be one rotation)
  kTripleOutsideWindow = 5,  ///< solved, but outside the voting window
};

/// Per-triple options shared by CPU and GPU.
struct TripleOptions {
  int32_t centroid_subtraction;  ///< 1: subtract the centroids before forming H (paper); 0: do not
  float min_separation;          ///< minimal chord |b_i - b_j| between bearings of a triple [rad]
  float min_triangle_area;       ///< minimal |(b2-b1)x(b3-b1)| / 2 of the triple [rad^2]
  float max_angle_change;        ///< max | |p_i-p_j| - |c_i-c_j| | over pairs [rad]; <= 0 disables
};

/// Swaps two (singular value, column of H V, column of V) triplets.
VG_HD void swapTriplet(float* sa, Vec3f* ha, Vec3f* va, float* sb, Vec3f* hb, Vec3f* vb) {
  const float s = *sa;
  *sa = *sb;
  *sb = s;
  const Vec3f h = *ha;
  *ha = *hb;
  *hb = h;
  const Vec3f v = *va;
  *va = *vb;
  *vb = v;
}

/// Solves R (b_prev ~ R b_cur) for one triple. Returns a TripleStatus; R is set only when kTripleOk.
VG_HD int32_t solveTripleRotation(const Vec3f prev[3], const Vec3f cur[3], const TripleOptions& opt,
                                  Mat3f* R) {
  // Degeneracy tests come first: they are cheap and reject most useless triples before the SVD.
  const Vec3f dp01 = prev[1] - prev[0], dp02 = prev[2] - prev[0], dp12 = prev[2] - prev[1];
  const Vec3f dc01 = cur[1] - cur[0], dc02 = cur[2] - cur[0], dc12 = cur[2] - cur[1];
  const float lp01 = norm(dp01), lp02 = norm(dp02), lp12 = norm(dp12);
  const float lc01 = norm(dc01), lc02 = norm(dc02), lc12 = norm(dc12);
  float shortest = fminf(fminf(lp01, lp02), fminf(lp12, fminf(lc01, fminf(lc02, lc12))));
  if (!(shortest >= opt.min_separation)) return kTripleRepeated;  // also catches NaN
  const float area = 0.5f * fminf(norm(cross(dp01, dp02)), norm(cross(dc01, dc02)));
  if (!(area >= opt.min_triangle_area)) return kTripleCollinear;
  if (opt.max_angle_change > 0.f) {
    const float change = fmaxf(fabsf(lp01 - lc01), fmaxf(fabsf(lp02 - lc02), fabsf(lp12 - lc12)));
    if (change > opt.max_angle_change) return kTripleInconsistent;
  }

  Vec3f p[3] = {cur[0], cur[1], cur[2]};   // source points (rotated by R)
  Vec3f q[3] = {prev[0], prev[1], prev[2]};  // target points
  if (opt.centroid_subtraction) {
    const Vec3f cp = (1.f / 3.f) * (p[0] + p[1] + p[2]);
    const Vec3f cq = (1.f / 3.f) * (q[0] + q[1] + q[2]);
    for (int i = 0; i < 3; ++i) {
      p[i] = p[i] - cp;
      q[i] = q[i] - cq;
    }
  }
  // H = sum p q^T (Arun's H with p = source, q = target); stored by columns h[c] for Jacobi.
  Vec3f h[3];
  h[0] = make3(p[0].x * q[0].x + p[1].x * q[1].x + p[2].x * q[2].x,
               p[0].y * q[0].x + p[1].y * q[1].x + p[2].y * q[2].x,
               p[0].z * q[0].x + p[1].z * q[1].x + p[2].z * q[2].x);
  h[1] = make3(p[0].x * q[0].y + p[1].x * q[1].y + p[2].x * q[2].y,
               p[0].y * q[0].y + p[1].y * q[1].y + p[2].y * q[2].y,
               p[0].z * q[0].y + p[1].z * q[1].y + p[2].z * q[2].y);
  h[2] = make3(p[0].x * q[0].z + p[1].x * q[1].z + p[2].x * q[2].z,
               p[0].y * q[0].z + p[1].y * q[1].z + p[2].y * q[2].z,
               p[0].z * q[0].z + p[1].z * q[1].z + p[2].z * q[2].z);
  const float detH = dot(h[0], cross(h[1], h[2]));
  // Without centroid subtraction H has full rank for any valid triple, and det(H) < 0 means no
  // rotation fits; with it H has rank 2 and the sign of det(H) carries no information.
  if (!opt.centroid_subtraction && !(detH > 0.f)) return kTripleReflection;

  // One-sided Jacobi: rotate column pairs of H (and of V) until they are orthogonal; then
  // H V = U S with U's columns the normalised columns of H V. Fixed sweep count: no divergence.
  // Jacobi converges quadratically: a sweep that finds every pair orthogonal to float precision
  // ends the iteration (typically after 3 to 4 of the at most 6 sweeps).
  Vec3f v[3] = {make3(1.f, 0.f, 0.f), make3(0.f, 1.f, 0.f), make3(0.f, 0.f, 1.f)};  // columns of V
  for (int sweep = 0; sweep < 6; ++sweep) {
    bool rotated = false;
    for (int pair = 0; pair < 3; ++pair) {
      const int i = pair == 2 ? 1 : 0;
      const int j = pair == 0 ? 1 : 2;
      const float alpha = dot(h[i], h[i]);
      const float beta = dot(h[j], h[j]);
      const float gamma = dot(h[i], h[j]);
      if (fabsf(gamma) <= 1e-7f * sqrtf(alpha * beta) || gamma == 0.f) continue;
      rotated = true;
      const float zeta = (beta - alpha) / (2.f * gamma);
      const float t = (zeta >= 0.f ? 1.f : -1.f) / (fabsf(zeta) + sqrtf(1.f + zeta * zeta));
      const float c = 1.f / sqrtf(1.f + t * t);
      const float s = c * t;
      const Vec3f hi = h[i], hj = h[j], vi = v[i], vj = v[j];
      h[i] = c * hi - s * hj;
      h[j] = s * hi + c * hj;
      v[i] = c * vi - s * vj;
      v[j] = s * vi + c * vj;
    }
    if (!rotated) break;
  }
  // Order by singular value so that the two largest define U; the third column of U is their
  // cross product (Kabsch/Umeyama det fix: R = V diag(1, 1, det V) U^T with a proper U).
  // Values are swapped rather than indexed: dynamic indexing would put the arrays in local memory
  // on the GPU. Strict comparisons keep the order of ties, identical on every backend.
  float s0 = norm(h[0]), s1 = norm(h[1]), s2 = norm(h[2]);
  Vec3f h0 = h[0], h1 = h[1], h2 = h[2];
  Vec3f v0 = v[0], v1 = v[1], v2 = v[2];
  if (s1 > s0) { swapTriplet(&s0, &h0, &v0, &s1, &h1, &v1); }
  if (s2 > s0) { swapTriplet(&s0, &h0, &v0, &s2, &h2, &v2); }
  if (s2 > s1) { swapTriplet(&s1, &h1, &v1, &s2, &h2, &v2); }
  (void)h2;
  if (!(s1 > 1e-7f * s0) || !(s0 > 0.f)) return kTripleCollinear;
  const Vec3f u0 = (1.f / s0) * h0;
  Vec3f u1 = h1 - dot(u0, h1) * u0;
  u1 = (1.f / norm(u1)) * u1;
  const Vec3f u2 = cross(u0, u1);
  const float detV = dot(v0, cross(v1, v2));
  if (detV < 0.f) v2 = -1.f * v2;
  // R = sum_k v_k u_k^T
  R->m[0] = v0.x * u0.x + v1.x * u1.x + v2.x * u2.x;
  R->m[1] = v0.x * u0.y + v1.x * u1.y + v2.x * u2.y;
  R->m[2] = v0.x * u0.z + v1.x * u1.z + v2.x * u2.z;
  R->m[3] = v0.y * u0.x + v1.y * u1.x + v2.y * u2.x;
  R->m[4] = v0.y * u0.y + v1.y * u1.y + v2.y * u2.y;
  R->m[5] = v0.y * u0.z + v1.y * u1.z + v2.y * u2.z;
  R->m[6] = v0.z * u0.x + v1.z * u1.x + v2.z * u2.x;
  R->m[7] = v0.z * u0.y + v1.z * u1.y + v2.z * u2.y;
  R->m[8] = v0.z * u0.z + v1.z * u1.z + v2.z * u2.z;
  return kTripleOk;
}

// ---------------------------------------------------------------------------------------------
// Angles of a rotation.
// ---------------------------------------------------------------------------------------------

/// Yaw of R: the angle about the camera's +y axis (down), from R = Ry(yaw) Rx(pitch) Rz(roll).
/// For a forward-looking camera a right turn is a positive yaw. [rad]
VG_HD float yawOf(const Mat3f& R) { return atan2f(R.m[2], R.m[8]); }

/// Rotation vector (axis * angle, rad) of R; accurate for angles well below pi, which is all a
/// frame-to-frame rotation can be.
VG_HD Vec3f rotationVectorOf(const Mat3f& R) {
  const Vec3f w = make3(R.m[7] - R.m[5], R.m[2] - R.m[6], R.m[3] - R.m[1]);  // 2 sin(a) axis
  const float s = 0.5f * norm(w);
  const float c = 0.5f * (R.m[0] + R.m[4] + R.m[8] - 1.f);
  const float angle = atan2f(s, c);
  const float scale = s > 1e-7f ? angle / (2.f * s) : 0.5f;
  return scale * w;
}

// ---------------------------------------------------------------------------------------------
// Vote grids.
// ---------------------------------------------------------------------------------------------

/// What a hypothesis votes with.
enum VoteKind : int32_t {
  kVoteYaw = 0,             ///< 1-D histogram of yaw (the paper)
  kVoteRotationVector = 1,  ///< 3-D histogram of the rotation vector
};

/// A regular histogram over [centre - half_width, centre + half_width) on each voted axis.
struct VoteGrid {
  int32_t kind;         ///< VoteKind
  float centre[3];      ///< window centre: yaw in centre[0], or a rotation vector [rad]
  float bin_width;      ///< [rad]
  int32_t bins;         ///< bins per axis; the histogram has bins (yaw) or bins^3 cells
};

/// Number of cells of a grid's histogram.
VG_HD int32_t cellCount(const VoteGrid& g) {
  return g.kind == kVoteYaw ? g.bins : g.bins * g.bins * g.bins;
}

VG_HD int32_t axisBin(float value, float centre, const VoteGrid& g) {
  const float pos = (value - centre) / g.bin_width + 0.5f * static_cast<float>(g.bins);
  if (!(pos >= 0.f) || pos >= static_cast<float>(g.bins)) return -1;
  return static_cast<int32_t>(pos);
}

/// Histogram cell of rotation R, or -1 when outside the window. *voted receives (yaw, pitch, roll)
/// for a yaw grid, the rotation vector for a rotation-vector grid.
/// Rotation-vector cells are indexed (ix * bins + iy) * bins + iz.
VG_HD int32_t cellOf(const Mat3f& R, const VoteGrid& g, Vec3f* voted) {
  if (g.kind == kVoteYaw) {
    // Pitch and roll ride along (not voted) so that a winning yaw bin still yields a 3-D rotation.
    const float yaw = yawOf(R);
    const float sin_pitch = fminf(1.f, fmaxf(-1.f, -R.m[5]));
    *voted = make3(yaw, asinf(sin_pitch), atan2f(R.m[3], R.m[4]));
    return axisBin(yaw, g.centre[0], g);
  }
  const Vec3f r = rotationVectorOf(R);
  *voted = r;
  const int32_t ix = axisBin(r.x, g.centre[0], g);
  const int32_t iy = axisBin(r.y, g.centre[1], g);
  const int32_t iz = axisBin(r.z, g.centre[2], g);
  if (ix < 0 || iy < 0 || iz < 0) return -1;
  return (ix * g.bins + iy) * g.bins + iz;
}

/// Centre of a 1-D bin [rad].
VG_HD float binCentre(int32_t bin, float centre, const VoteGrid& g) {
  return centre + (static_cast<float>(bin) + 0.5f - 0.5f * static_cast<float>(g.bins)) * g.bin_width;
}

/// What one hypothesis produced; kept for the bin-for-bin CPU/GPU comparison and for reading the
/// estimate from the hypotheses of the winning cell.
struct HypothesisRecord {
  float value[3];  ///< yaw grid: (yaw, pitch, roll); rotation grid: the rotation vector [rad]
  int32_t cell;    ///< histogram cell, -1 when rejected or outside the window
};

/// The bearings of hypothesis `h`'s triple (drawTriple) in the previous (tp) and current (tc) frame.
VG_HD void loadTriple(const Vec3f* prev, const Vec3f* cur, uint32_t n, uint64_t seed, uint32_t h,
                      Vec3f tp[3], Vec3f tc[3]) {
  uint32_t idx[3];
  drawTriple(seed, h, n, idx);
  tp[0] = prev[idx[0]];
  tp[1] = prev[idx[1]];
  tp[2] = prev[idx[2]];
  tc[0] = cur[idx[0]];
  tc[1] = cur[idx[1]];
  tc[2] = cur[idx[2]];
}

/// Bins a hypothesis given what solveTripleRotation returned for it (`status`, and R when
/// kTripleOk). Returns the TripleStatus (kTripleOutsideWindow when solved but not in the grid).
VG_HD int32_t binHypothesis(int32_t status, const Mat3f& R, const VoteGrid& grid, HypothesisRecord* out) {
  out->cell = -1;
  out->value[0] = out->value[1] = out->value[2] = 0.f;
  if (status != kTripleOk) return status;
  Vec3f voted;
  out->cell = cellOf(R, grid, &voted);
  out->value[0] = voted.x;
  out->value[1] = voted.y;
  out->value[2] = voted.z;
  return out->cell >= 0 ? kTripleOk : kTripleOutsideWindow;
}

/// Draws, solves and bins hypothesis `h`: the whole per-thread work of the voting RANSAC.
/// Returns the TripleStatus (kTripleOutsideWindow when solved but not in the grid).
VG_HD int32_t evaluateHypothesis(const Vec3f* prev, const Vec3f* cur, uint32_t n, uint64_t seed,
                                 uint32_t h, const TripleOptions& opt, const VoteGrid& grid,
                                 HypothesisRecord* out) {
  Vec3f tp[3], tc[3];
  loadTriple(prev, cur, n, seed, h, tp, tc);
  Mat3f R;
  const int32_t status = solveTripleRotation(tp, tc, opt, &R);
  return binHypothesis(status, R, grid, out);
}

}  // namespace hyp
}  // namespace visual_gyro
