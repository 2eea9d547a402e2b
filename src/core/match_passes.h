// The loops over every match of the verification and the refinement (rotation_refinement.cpp),
// each compiled for the build's baseline and for AVX2, the variant chosen once by the CPU. Both
// variants perform the same floating-point operations in the same order (no fused multiply-add
// in either), so the results do not depend on the CPU. Private to src/core.
#pragma once

#include <algorithm>
#include <cstddef>

#include "cpu_features.h"

namespace visual_gyro {
namespace passes {

/// Squared symmetric Sampson-style norm of the gradient of the epipolar residual t.(p x Rc), from
/// tp = t.p and trc = t.Rc (|t x v|^2 = 1 - (t.v)^2 for unit vectors), floored. The residual over
/// this norm is the angular distance of the match from its epipolar plane: the algebraic residual
/// shrinks with the distance of the bearings from the epipole, so wrong matches near the focus of
/// expansion would pass an algebraic gate as easily as right ones; the angular one treats every
/// match alike.
inline double sampsonNorm2(double tp, double trc) { return std::max(1.0 - 0.5 * (tp * tp + trc * trc), 1e-6); }

/// Bearings and the quantities of one rotation R, structure of arrays: p = b_prev, c = b_cur,
/// r = R c, n = p x R c, and `facing` = p . R c (the match is usable when it is positive).
struct MatchArrays {
  const double *px, *py, *pz;
  const double *rx, *ry, *rz;
  const double *nx, *ny, *nz;
  const double* facing;
};

/// Chunk length of the normal-equation sums.
constexpr int kChunk = 32;

/// Per-chunk sums of the epipolar normal equations (see sumEpipolar), added to by each chunk.
struct EpipolarSums {
  double a[15] = {};  ///< upper triangle of J^T W J by rows, the rotation part without its R^T
  double g[5] = {};   ///< J^T W r, likewise
  double cost = 0.0;  ///< Tukey cost, or the sum of squared residuals of the inliers
  int used = 0;       ///< matches summed (Tukey), or the inliers
};

/// The variants' functions.
struct PassTable {
  /// r, n and facing of matches 0..n-1 at rotation R (row-major entries R[9]) from p and c.
  void (*rotate)(size_t n, const double* R, const double* px, const double* py, const double* pz, const double* cx,
                 const double* cy, const double* cz, double* rx, double* ry, double* rz, double* nx, double* ny,
                 double* nz, double* facing);
  /// Matches in [begin, end) of `m` (facing unused: all usable) within the epipolar gate of t:
  /// (t.n)^2 < gate2 * sampsonNorm2(t.p, t.r).
  int (*countWithinGate)(const MatchArrays& m, size_t begin, size_t end, const double* t, double gate2);
  /// w[i] = 1 / sampsonNorm2(t.p, t.r) for the usable matches within the gate as countWithinGate
  /// tests it, 0 for the others; i < n.
  void (*gateWeights)(const MatchArrays& m, size_t n, const double* t, double gate2, double* w);
  /// w[i] = Huber weight (1 up to k, then k / |n|) of the usable matches with |n|^2 < gate2, 0 for
  /// the others; i < n.
  void (*huberWeights)(const MatchArrays& m, size_t n, double gate2, double k, double* w);
  /// r2[i] = (t.n)^2 / sampsonNorm2(t.p, t.r), the squared angular epipolar residual, or with
  /// t == nullptr |n|^2, the squared pure-rotation residual; i < n.
  void (*residuals2)(const MatchArrays& m, size_t n, const double* t, double* r2);
  /// Adds the epipolar normal equations of the gathered matches (gp*, gc*: b_prev, b_cur laid out
  /// as gatheredPosition places them for `interleaved`, `count` of them padded with zero bearings to whole chunks)
  /// at rotation R (row-major R[9]) and unit translation t with tangent basis B (column-major
  /// B[6]) to `sums`: Tukey weights with cut-off `gate` (`tukey`), or unit weights for the usable
  /// matches whose residual is below `gate`.
  void (*sumEpipolar)(const double* gpx, const double* gpy, const double* gpz, const double* gcx, const double* gcy,
                      const double* gcz, size_t count, const double* R, const double* t, const double* B, double gate,
                      bool tukey, EpipolarSums* sums);
  /// The Tukey cost sumEpipolar adds up (tukey), alone: for a step whose normal equations are not
  /// needed. The same value, summed in the same order.
  double (*tukeyCost)(const double* gpx, const double* gpy, const double* gpz, const double* gcx, const double* gcy,
                      const double* gcz, size_t count, const double* R, const double* t, double gate);
  /// How sumEpipolar wants the gathered matches laid out (see gatheredPosition).
  bool interleaved;
};

/// Where the k-th gathered match goes in the gathered arrays: k itself, or (`interleaved`) a
/// position within its chunk that gives a 4-lane vector two of Eigen's SSE2 packets: vector v of a
/// chunk holds packet v (matches 2v, 2v + 1) in its low and packet v + 8 in its high half.
inline size_t gatheredPosition(size_t k, bool interleaved) {
  if (!interleaved) return k;
  const size_t e = k % kChunk, packet = e / 2;
  return k - e + (packet % 8) * 4 + (packet / 8) * 2 + e % 2;
}

/// The k-th smallest of a[0..n) (k < n; a is reordered): the value std::nth_element leaves at a[k],
/// found by partitions without data-dependent branches.
double selectKth(double* a, size_t n, size_t k);

/// The variant of `level`: the baseline one (kPortable: compiled for the build's target, Eigen's
/// SSE2 packets on x86-64), the AVX2 one (kAvx2; none in a build for a wider target, see
/// match_passes.cpp); nullptr for other levels or when this CPU cannot run it.
const PassTable* passTableFor(cpu::CpuLevel level);
/// The variant of the highest level this CPU runs (cpu::activeLevel(); chosen once).
const PassTable& passes();

}  // namespace passes
}  // namespace visual_gyro
