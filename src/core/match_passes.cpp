// The per-match loops of rotation_refinement.cpp and their AVX2 variants. The plain loops are
// written for the compiler's vectoriser (no branches, arrays as restrict parameters) and compiled
// twice: once for the baseline, once inside an AVX2 function (twice the lanes). The normal-equation
// sums keep Eigen's SSE2 array expressions as the baseline; the AVX2 variant computes the same
// values four matches at a time and adds them up in the order Eigen's SSE2 reductions do (see
// sumEpipolarAvx2).
#include "match_passes.h"

#include <Eigen/Core>
#include <cmath>
#include <cstdint>

// The AVX2 variant reproduces a baseline compiled for plain x86-64: Eigen's SSE2 packets and no
// fused multiply-add. A build for a wider target (AVX or FMA enabled for the whole file) has
// neither, and its baseline is already vectorised for that target: it then runs alone.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__AVX__) && !defined(__FMA__)
#include <immintrin.h>
#define VG_MATCH_PASSES_AVX2 1
#endif

namespace visual_gyro {
namespace passes {

namespace {

#define VG_BODY inline __attribute__((always_inline))

VG_BODY void rotateBody(size_t n, const double* R, const double* __restrict px, const double* __restrict py,
                        const double* __restrict pz, const double* __restrict cx, const double* __restrict cy,
                        const double* __restrict cz, double* __restrict out_rx, double* __restrict out_ry,
                        double* __restrict out_rz, double* __restrict out_nx, double* __restrict out_ny,
                        double* __restrict out_nz, double* __restrict facing) {
  const double r00 = R[0], r01 = R[1], r02 = R[2];
  const double r10 = R[3], r11 = R[4], r12 = R[5];
  const double r20 = R[6], r21 = R[7], r22 = R[8];
  for (size_t i = 0; i < n; ++i) {
    const double rx = r00 * cx[i] + r01 * cy[i] + r02 * cz[i];
    const double ry = r10 * cx[i] + r11 * cy[i] + r12 * cz[i];
    const double rz = r20 * cx[i] + r21 * cy[i] + r22 * cz[i];
    out_rx[i] = rx;
    out_ry[i] = ry;
    out_rz[i] = rz;
    out_nx[i] = py[i] * rz - pz[i] * ry;
    out_ny[i] = pz[i] * rx - px[i] * rz;
    out_nz[i] = px[i] * ry - py[i] * rx;
    facing[i] = px[i] * rx + py[i] * ry + pz[i] * rz;
  }
}

VG_BODY int countBody(const MatchArrays& m, size_t begin, size_t end, const double* t, double gate2) {
  const double tx = t[0], ty = t[1], tz = t[2];
  // A 64-bit count, as wide as the comparisons' lanes: the vectorised loop adds their masks as they
  // are, without packing them to 32 bits first.
  int64_t count = 0;
  for (size_t i = begin; i < end; ++i) {
    const double algebraic = tx * m.nx[i] + ty * m.ny[i] + tz * m.nz[i];
    const double tp = tx * m.px[i] + ty * m.py[i] + tz * m.pz[i];
    const double trc = tx * m.rx[i] + ty * m.ry[i] + tz * m.rz[i];
    count += algebraic * algebraic < gate2 * sampsonNorm2(tp, trc);
  }
  return static_cast<int>(count);
}

VG_BODY void residualsBody(size_t n, const double* t, const double* __restrict px, const double* __restrict py,
                           const double* __restrict pz, const double* __restrict rx, const double* __restrict ry,
                           const double* __restrict rz, const double* __restrict nx, const double* __restrict ny,
                           const double* __restrict nz, double* __restrict r2) {
  if (t == nullptr) {
    for (size_t i = 0; i < n; ++i) r2[i] = nx[i] * nx[i] + ny[i] * ny[i] + nz[i] * nz[i];
    return;
  }
  const double tx = t[0], ty = t[1], tz = t[2];
  for (size_t i = 0; i < n; ++i) {
    const double algebraic = tx * nx[i] + ty * ny[i] + tz * nz[i];
    const double tp = tx * px[i] + ty * py[i] + tz * pz[i];
    const double trc = tx * rx[i] + ty * ry[i] + tz * rz[i];
    r2[i] = algebraic * algebraic / sampsonNorm2(tp, trc);
  }
}

#undef VG_BODY

void rotateBaseline(size_t n, const double* R, const double* px, const double* py, const double* pz, const double* cx,
                    const double* cy, const double* cz, double* rx, double* ry, double* rz, double* nx, double* ny,
                    double* nz, double* facing) {
  rotateBody(n, R, px, py, pz, cx, cy, cz, rx, ry, rz, nx, ny, nz, facing);
}

int countBaseline(const MatchArrays& m, size_t begin, size_t end, const double* t, double gate2) {
  return countBody(m, begin, end, t, gate2);
}

void weightsBaseline(const MatchArrays& m, size_t n, const double* t, double gate2, double* w) {
  const double tx = t[0], ty = t[1], tz = t[2];
  for (size_t i = 0; i < n; ++i) {
    const double algebraic = tx * m.nx[i] + ty * m.ny[i] + tz * m.nz[i];
    const double tp = tx * m.px[i] + ty * m.py[i] + tz * m.pz[i];
    const double trc = tx * m.rx[i] + ty * m.ry[i] + tz * m.rz[i];
    const double norm2 = sampsonNorm2(tp, trc);
    w[i] = m.facing[i] > 0.0 && algebraic * algebraic < gate2 * norm2 ? 1.0 / norm2 : 0.0;
  }
}

void huberBaseline(const MatchArrays& m, size_t n, double gate2, double k, double* w) {
  for (size_t i = 0; i < n; ++i) {
    const double r2 = m.nx[i] * m.nx[i] + m.ny[i] * m.ny[i] + m.nz[i] * m.nz[i];
    const double a = std::abs(std::sqrt(r2));
    w[i] = m.facing[i] > 0.0 && r2 < gate2 ? (a <= k ? 1.0 : k / a) : 0.0;
  }
}

void residualsBaseline(const MatchArrays& m, size_t n, const double* t, double* r2) {
  residualsBody(n, t, m.px, m.py, m.pz, m.rx, m.ry, m.rz, m.nx, m.ny, m.nz, r2);
}

// The Jacobian rows and residuals of the epipolar cost, summed by chunks of array expressions
// (vectorised by Eigen); the gathered matches in index order.
/// One chunk's rotated current bearings R b_cur, epipolar normals n = b_prev x R b_cur, Sampson
/// scales and normalised residuals r = (t . n) * scale (R row-major, t the unit translation).
struct EpipolarChunk {
  using Chunk = Eigen::Array<double, kChunk, 1>;
  Chunk rx, ry, rz, nx, ny, nz, scale, r;
};

EpipolarChunk epipolarChunk(const double* gpx, const double* gpy, const double* gpz, const double* gcx,
                            const double* gcy, const double* gcz, size_t start, const double* R_, const double* t) {
  using Chunk = EpipolarChunk::Chunk;
  const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> R(R_);
  const double tx = t[0], ty = t[1], tz = t[2];
  const Eigen::Map<const Chunk> px(gpx + start), py(gpy + start), pz(gpz + start);
  const Eigen::Map<const Chunk> cx(gcx + start), cy(gcy + start), cz(gcz + start);
  EpipolarChunk e;
  e.rx = R(0, 0) * cx + R(0, 1) * cy + R(0, 2) * cz;
  e.ry = R(1, 0) * cx + R(1, 1) * cy + R(1, 2) * cz;
  e.rz = R(2, 0) * cx + R(2, 1) * cy + R(2, 2) * cz;
  e.nx = py * e.rz - pz * e.ry, e.ny = pz * e.rx - px * e.rz, e.nz = px * e.ry - py * e.rx;
  const Chunk tp = tx * px + ty * py + tz * pz, trc = tx * e.rx + ty * e.ry + tz * e.rz;
  e.scale = (1.0 - 0.5 * (tp.square() + trc.square())).max(1e-6).sqrt().inverse();
  e.r = (tx * e.nx + ty * e.ny + tz * e.nz) * e.scale;
  return e;
}

void sumEpipolarBaseline(const double* gpx, const double* gpy, const double* gpz, const double* gcx,
                         const double* gcy, const double* gcz, size_t count, const double* R_, const double* t,
                         const double* B_, double gate, bool tukey, EpipolarSums* sums) {
  using Chunk = Eigen::Array<double, kChunk, 1>;
  const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> R(R_);
  const Eigen::Map<const Eigen::Matrix<double, 3, 2>> B(B_);
  const double tx = t[0], ty = t[1], tz = t[2];
  double* a = sums->a;
  double* g = sums->g;
  for (size_t start = 0; start < count; start += kChunk) {
    const int len = static_cast<int>(std::min<size_t>(kChunk, count - start));
    const Eigen::Map<const Chunk> px(gpx + start), py(gpy + start), pz(gpz + start);
    // Iteratively reweighted: the scale is held fixed within a step (Sampson's approximation).
    const EpipolarChunk e = epipolarChunk(gpx, gpy, gpz, gcx, gcy, gcz, start, R_, t);
    const Chunk &rx = e.rx, &ry = e.ry, &rz = e.rz, &nx = e.nx, &ny = e.ny, &nz = e.nz;
    const Chunk &scale = e.scale, &r = e.r;
    Chunk w;
    if (tukey) {
      // Tukey's biweight with cut-off `gate`: matches near the gate, most likely wrong ones that
      // slipped in, lose their influence smoothly instead of pulling with a constant (Huber) force.
      const Chunk u2 = (r * (1.0 / gate)).square();
      w = (u2 < 1.0).select((1.0 - u2).square(), 0.0);
      sums->cost += gate * gate / 6.0 * (1.0 - (1.0 - u2.min(1.0)).cube()).sum();
      sums->used += len;
    } else {
      w = (r.abs() < gate && px * rx + py * ry + pz * rz > 0.0).select(Chunk::Ones(), Chunk::Zero());
      sums->cost += (w * r.square()).sum();
      sums->used += static_cast<int>(w.sum());
    }
    const Chunk qx = ty * pz - tz * py, qy = tz * px - tx * pz, qz = tx * py - ty * px;  // t x p
    const Chunk j[5] = {qz * ry - qy * rz, qx * rz - qz * rx, qy * rx - qx * ry,
                        nx * B(0, 0) + ny * B(1, 0) + nz * B(2, 0), nx * B(0, 1) + ny * B(1, 1) + nz * B(2, 1)};
    const Chunk ws = w * scale.square(), wr = w * r * scale;
    int k = 0;
    for (int row = 0; row < 5; ++row) {
      g[row] += (wr * j[row]).sum();
      const Chunk wj = ws * j[row];
      for (int col = row; col < 5; ++col) a[k++] += (wj * j[col]).sum();
    }
  }
}

double tukeyCostBaseline(const double* gpx, const double* gpy, const double* gpz, const double* gcx, const double* gcy,
                         const double* gcz, size_t count, const double* R_, const double* t, double gate) {
  using Chunk = Eigen::Array<double, kChunk, 1>;
  double cost = 0.0;
  for (size_t start = 0; start < count; start += kChunk) {
    const Chunk r = epipolarChunk(gpx, gpy, gpz, gcx, gcy, gcz, start, R_, t).r;
    const Chunk u2 = (r * (1.0 / gate)).square();
    cost += gate * gate / 6.0 * (1.0 - (1.0 - u2.min(1.0)).cube()).sum();
  }
  return cost;
}

const PassTable kBaseline = {rotateBaseline,      countBaseline,     weightsBaseline, huberBaseline,
                             residualsBaseline,   sumEpipolarBaseline, tukeyCostBaseline, false};

#ifdef VG_MATCH_PASSES_AVX2

__attribute__((target("avx2"))) void rotateAvx2(size_t n, const double* R, const double* px, const double* py,
                                                const double* pz, const double* cx, const double* cy, const double* cz,
                                                double* rx, double* ry, double* rz, double* nx, double* ny, double* nz,
                                                double* facing) {
  rotateBody(n, R, px, py, pz, cx, cy, cz, rx, ry, rz, nx, ny, nz, facing);
}

__attribute__((target("avx2"))) int countAvx2(const MatchArrays& m, size_t begin, size_t end, const double* t,
                                              double gate2) {
  return countBody(m, begin, end, t, gate2);
}

__attribute__((target("avx2"))) inline __m256d add(__m256d x, __m256d y) { return _mm256_add_pd(x, y); }
__attribute__((target("avx2"))) inline __m256d sub(__m256d x, __m256d y) { return _mm256_sub_pd(x, y); }
__attribute__((target("avx2"))) inline __m256d mul(__m256d x, __m256d y) { return _mm256_mul_pd(x, y); }

// sampsonNorm2 of four matches, operation for operation.
__attribute__((target("avx2"))) inline __m256d sampsonNorm2Lanes(__m256d tp, __m256d trc) {
  const __m256d one = _mm256_set1_pd(1.0), half = _mm256_set1_pd(0.5), floor = _mm256_set1_pd(1e-6);
  return _mm256_max_pd(sub(one, mul(half, add(mul(tp, tp), mul(trc, trc)))), floor);
}

// weightsBaseline four matches per instruction. Written out: the compiler turns the plain loop's
// 1 / max(x, 1e-6) into a branch around the division, which it then cannot vectorise.
__attribute__((target("avx2"))) void weightsAvx2(const MatchArrays& m, size_t n, const double* t, double gate2,
                                                 double* w) {
  const __m256d tx = _mm256_set1_pd(t[0]), ty = _mm256_set1_pd(t[1]), tz = _mm256_set1_pd(t[2]);
  const __m256d one = _mm256_set1_pd(1.0);
  const __m256d gate2_v = _mm256_set1_pd(gate2), zero = _mm256_setzero_pd();
  size_t i = 0;
  for (; i + 4 <= n; i += 4) {
    const __m256d algebraic = add(add(mul(tx, _mm256_loadu_pd(m.nx + i)), mul(ty, _mm256_loadu_pd(m.ny + i))),
                                  mul(tz, _mm256_loadu_pd(m.nz + i)));
    const __m256d tp = add(add(mul(tx, _mm256_loadu_pd(m.px + i)), mul(ty, _mm256_loadu_pd(m.py + i))),
                           mul(tz, _mm256_loadu_pd(m.pz + i)));
    const __m256d trc = add(add(mul(tx, _mm256_loadu_pd(m.rx + i)), mul(ty, _mm256_loadu_pd(m.ry + i))),
                            mul(tz, _mm256_loadu_pd(m.rz + i)));
    const __m256d norm2 = sampsonNorm2Lanes(tp, trc);
    const __m256d inside =
        _mm256_and_pd(_mm256_cmp_pd(_mm256_loadu_pd(m.facing + i), zero, _CMP_GT_OQ),
                      _mm256_cmp_pd(mul(algebraic, algebraic), mul(gate2_v, norm2), _CMP_LT_OQ));
    _mm256_storeu_pd(w + i, _mm256_and_pd(inside, _mm256_div_pd(one, norm2)));
  }
  for (; i < n; ++i) {
    const double algebraic = t[0] * m.nx[i] + t[1] * m.ny[i] + t[2] * m.nz[i];
    const double tp = t[0] * m.px[i] + t[1] * m.py[i] + t[2] * m.pz[i];
    const double trc = t[0] * m.rx[i] + t[1] * m.ry[i] + t[2] * m.rz[i];
    const double norm2 = sampsonNorm2(tp, trc);
    w[i] = m.facing[i] > 0.0 && algebraic * algebraic < gate2 * norm2 ? 1.0 / norm2 : 0.0;
  }
}

// huberBaseline four matches per instruction (its square root and quotient vectorised).
__attribute__((target("avx2"))) void huberAvx2(const MatchArrays& m, size_t n, double gate2, double k, double* w) {
  const __m256d gate2_v = _mm256_set1_pd(gate2), k_v = _mm256_set1_pd(k), one = _mm256_set1_pd(1.0);
  const __m256d zero = _mm256_setzero_pd(), sign = _mm256_set1_pd(-0.0);
  size_t i = 0;
  for (; i + 4 <= n; i += 4) {
    const __m256d nx = _mm256_loadu_pd(m.nx + i), ny = _mm256_loadu_pd(m.ny + i), nz = _mm256_loadu_pd(m.nz + i);
    const __m256d r2 = add(add(mul(nx, nx), mul(ny, ny)), mul(nz, nz));
    const __m256d a = _mm256_andnot_pd(sign, _mm256_sqrt_pd(r2));
    const __m256d huber = _mm256_blendv_pd(_mm256_div_pd(k_v, a), one, _mm256_cmp_pd(a, k_v, _CMP_LE_OQ));
    const __m256d inside = _mm256_and_pd(_mm256_cmp_pd(_mm256_loadu_pd(m.facing + i), zero, _CMP_GT_OQ),
                                         _mm256_cmp_pd(r2, gate2_v, _CMP_LT_OQ));
    _mm256_storeu_pd(w + i, _mm256_and_pd(inside, huber));
  }
  for (; i < n; ++i) {
    const double r2 = m.nx[i] * m.nx[i] + m.ny[i] * m.ny[i] + m.nz[i] * m.nz[i];
    const double a = std::abs(std::sqrt(r2));
    w[i] = m.facing[i] > 0.0 && r2 < gate2 ? (a <= k ? 1.0 : k / a) : 0.0;
  }
}

__attribute__((target("avx2"))) void residualsAvx2(const MatchArrays& m, size_t n, const double* t, double* r2) {
  residualsBody(n, t, m.px, m.py, m.pz, m.rx, m.ry, m.rz, m.nx, m.ny, m.nz, r2);
}

// Eigen's SSE2 sum of 32 doubles (a fully unrolled reduction) adds its 16 two-double packets P0..P15
// pairwise, as a balanced tree, then the two lanes of the result. Vector k of a chunk here holds
// P_k in its low and P_{k+8} in its high half (gatheredPosition, interleaved), so the same tree over the eight
// vectors adds P0..P7 in the low and P8..P15 in the high halves, and the halves' sum and its two
// lanes finish exactly as Eigen does.
__attribute__((target("avx2"))) inline double sumLikeEigen(const __m256d v[8]) {
  const __m256d s = _mm256_add_pd(_mm256_add_pd(_mm256_add_pd(v[0], v[1]), _mm256_add_pd(v[2], v[3])),
                                  _mm256_add_pd(_mm256_add_pd(v[4], v[5]), _mm256_add_pd(v[6], v[7])));
  const __m128d h = _mm_add_pd(_mm256_castpd256_pd128(s), _mm256_extractf128_pd(s, 1));
  return _mm_cvtsd_f64(_mm_add_sd(h, _mm_unpackhi_pd(h, h)));
}

// The rotation and translation broadcast to four lanes.
struct MotionLanes {
  __attribute__((target("avx2"))) MotionLanes(const double* R, const double* t) {
    for (int i = 0; i < 9; ++i) r[i] = _mm256_set1_pd(R[i]);
    for (int i = 0; i < 3; ++i) this->t[i] = _mm256_set1_pd(t[i]);
  }
  __m256d r[9], t[3];
};

// Four matches' rotated current bearing R b_cur, epipolar normal n = b_prev x R b_cur, Sampson
// scale and normalised residual r = (t . n) * scale, each operation in the baseline's order.
struct EpipolarLanes {
  __m256d px, py, pz, rx, ry, rz, nx, ny, nz, scale, r;
};

__attribute__((target("avx2"))) inline EpipolarLanes epipolarLanes(const double* gpx, const double* gpy,
                                                                   const double* gpz, const double* gcx,
                                                                   const double* gcy, const double* gcz, size_t at,
                                                                   const MotionLanes& m) {
  const __m256d one = _mm256_set1_pd(1.0);
  const __m256d* R = m.r;
  const __m256d tx = m.t[0], ty = m.t[1], tz = m.t[2];
  EpipolarLanes e;
  e.px = _mm256_loadu_pd(gpx + at), e.py = _mm256_loadu_pd(gpy + at), e.pz = _mm256_loadu_pd(gpz + at);
  const __m256d cx = _mm256_loadu_pd(gcx + at), cy = _mm256_loadu_pd(gcy + at), cz = _mm256_loadu_pd(gcz + at);
  e.rx = add(add(mul(R[0], cx), mul(R[1], cy)), mul(R[2], cz));
  e.ry = add(add(mul(R[3], cx), mul(R[4], cy)), mul(R[5], cz));
  e.rz = add(add(mul(R[6], cx), mul(R[7], cy)), mul(R[8], cz));
  e.nx = sub(mul(e.py, e.rz), mul(e.pz, e.ry)), e.ny = sub(mul(e.pz, e.rx), mul(e.px, e.rz));
  e.nz = sub(mul(e.px, e.ry), mul(e.py, e.rx));
  const __m256d tp = add(add(mul(tx, e.px), mul(ty, e.py)), mul(tz, e.pz));
  const __m256d trc = add(add(mul(tx, e.rx), mul(ty, e.ry)), mul(tz, e.rz));
  const __m256d norm2 = sampsonNorm2Lanes(tp, trc);
  e.scale = _mm256_div_pd(one, _mm256_sqrt_pd(norm2));
  e.r = mul(add(add(mul(tx, e.nx), mul(ty, e.ny)), mul(tz, e.nz)), e.scale);
  return e;
}

// sumEpipolarBaseline four matches per instruction, operation for operation (each product, sum
// and quotient in the baseline's order), the sums in the baseline's order (sumLikeEigen). The
// Tukey cost's reduction is not fully unrolled by Eigen (two running packets instead of a tree):
// its terms are put back in index order and summed by the baseline's own expression.
__attribute__((target("avx2"))) void sumEpipolarAvx2(const double* gpx, const double* gpy, const double* gpz,
                                                     const double* gcx, const double* gcy, const double* gcz,
                                                     size_t count, const double* R, const double* t, const double* B,
                                                     double gate, bool tukey, EpipolarSums* sums) {
  using Chunk = Eigen::Array<double, kChunk, 1>;
  const MotionLanes motion(R, t);
  const __m256d tx = motion.t[0], ty = motion.t[1], tz = motion.t[2];
  const __m256d b00 = _mm256_set1_pd(B[0]), b10 = _mm256_set1_pd(B[1]), b20 = _mm256_set1_pd(B[2]);
  const __m256d b01 = _mm256_set1_pd(B[3]), b11 = _mm256_set1_pd(B[4]), b21 = _mm256_set1_pd(B[5]);
  const __m256d one = _mm256_set1_pd(1.0);
  const __m256d zero = _mm256_setzero_pd(), gate_v = _mm256_set1_pd(gate);
  const __m256d inverse_gate = _mm256_set1_pd(1.0 / gate);
  const __m256d sign = _mm256_set1_pd(-0.0);
  for (size_t start = 0; start < count; start += kChunk) {
    const int len = static_cast<int>(std::min<size_t>(kChunk, count - start));
    __m256d products[20][8];
    __m256d squares[8], weights[8];
    Chunk u2_chunk;
    for (int k = 0; k < 8; ++k) {
      const EpipolarLanes e4 = epipolarLanes(gpx, gpy, gpz, gcx, gcy, gcz, start + 4 * k, motion);
      const __m256d px = e4.px, py = e4.py, pz = e4.pz, rx = e4.rx, ry = e4.ry, rz = e4.rz;
      const __m256d nx = e4.nx, ny = e4.ny, nz = e4.nz, scale = e4.scale, r = e4.r;
      __m256d w;
      if (tukey) {
        const __m256d ru = mul(r, inverse_gate);
        const __m256d u2 = mul(ru, ru);
        const __m256d rest = sub(one, u2);
        w = _mm256_blendv_pd(zero, mul(rest, rest), _mm256_cmp_pd(u2, one, _CMP_LT_OQ));
        _mm_storeu_pd(u2_chunk.data() + 2 * k, _mm256_castpd256_pd128(u2));
        _mm_storeu_pd(u2_chunk.data() + 2 * k + 16, _mm256_extractf128_pd(u2, 1));
      } else {
        const __m256d facing = add(add(mul(px, rx), mul(py, ry)), mul(pz, rz));
        const __m256d inside = _mm256_and_pd(_mm256_cmp_pd(_mm256_andnot_pd(sign, r), gate_v, _CMP_LT_OQ),
                                             _mm256_cmp_pd(facing, zero, _CMP_GT_OQ));
        w = _mm256_and_pd(inside, one);
        squares[k] = mul(w, mul(r, r));
        weights[k] = w;
      }
      const __m256d qx = sub(mul(ty, pz), mul(tz, py)), qy = sub(mul(tz, px), mul(tx, pz));
      const __m256d qz = sub(mul(tx, py), mul(ty, px));
      const __m256d j[5] = {sub(mul(qz, ry), mul(qy, rz)), sub(mul(qx, rz), mul(qz, rx)), sub(mul(qy, rx), mul(qx, ry)),
                            add(add(mul(nx, b00), mul(ny, b10)), mul(nz, b20)),
                            add(add(mul(nx, b01), mul(ny, b11)), mul(nz, b21))};
      const __m256d ws = mul(w, mul(scale, scale)), wr = mul(mul(w, r), scale);
      int e = 0;
      for (int row = 0; row < 5; ++row) {
        products[e++][k] = mul(wr, j[row]);
        const __m256d wj = mul(ws, j[row]);
        for (int col = row; col < 5; ++col) products[e++][k] = mul(wj, j[col]);
      }
    }
    int e = 0, entry = 0;
    for (int row = 0; row < 5; ++row) {
      sums->g[row] += sumLikeEigen(products[e++]);
      for (int col = row; col < 5; ++col) sums->a[entry++] += sumLikeEigen(products[e++]);
    }
    if (tukey) {
      const Chunk u2 = u2_chunk;
      sums->cost += gate * gate / 6.0 * (1.0 - (1.0 - u2.min(1.0)).cube()).sum();
      sums->used += len;
    } else {
      sums->cost += sumLikeEigen(squares);
      sums->used += static_cast<int>(sumLikeEigen(weights));
    }
  }
}

// tukeyCostBaseline four matches per instruction (the first part of sumEpipolarAvx2).
__attribute__((target("avx2"))) double tukeyCostAvx2(const double* gpx, const double* gpy, const double* gpz,
                                                     const double* gcx, const double* gcy, const double* gcz,
                                                     size_t count, const double* R, const double* t, double gate) {
  using Chunk = Eigen::Array<double, kChunk, 1>;
  const MotionLanes motion(R, t);
  const __m256d inverse_gate = _mm256_set1_pd(1.0 / gate);
  double cost = 0.0;
  for (size_t start = 0; start < count; start += kChunk) {
    Chunk u2_chunk;
    for (int k = 0; k < 8; ++k) {
      const __m256d r = epipolarLanes(gpx, gpy, gpz, gcx, gcy, gcz, start + 4 * k, motion).r;
      const __m256d ru = mul(r, inverse_gate);
      const __m256d u2 = mul(ru, ru);
      _mm_storeu_pd(u2_chunk.data() + 2 * k, _mm256_castpd256_pd128(u2));
      _mm_storeu_pd(u2_chunk.data() + 2 * k + 16, _mm256_extractf128_pd(u2, 1));
    }
    const Chunk u2 = u2_chunk;
    cost += gate * gate / 6.0 * (1.0 - (1.0 - u2.min(1.0)).cube()).sum();
  }
  return cost;
}

const PassTable kAvx2 = {rotateAvx2,      countAvx2,       weightsAvx2,   huberAvx2,
                         residualsAvx2,   sumEpipolarAvx2, tukeyCostAvx2, true};

#endif

}  // namespace

double selectKth(double* a, size_t n, size_t k) {
  // Quickselect on a median-of-three pivot. Each partition writes every element (a swap with the
  // partition's end, which only the smaller ones then advance) instead of branching on its side:
  // the sides of the median of residuals are a coin toss, which a branch predictor cannot learn.
  size_t lo = 0, hi = n;
  while (hi - lo > 24) {
    const double x = a[lo], y = a[lo + (hi - lo) / 2], z = a[hi - 1];
    const double pivot = std::max(std::min(x, y), std::min(std::max(x, y), z));
    size_t below = lo;  // [lo, below) < pivot
    for (size_t i = lo; i < hi; ++i) {
      const double v = a[i];
      a[i] = a[below];
      a[below] = v;
      below += v < pivot;
    }
    if (k < below) {
      hi = below;
      continue;
    }
    size_t equal = below;  // [below, equal) == pivot: at least the pivot itself, so the range shrinks
    for (size_t i = below; i < hi; ++i) {
      const double v = a[i];
      a[i] = a[equal];
      a[equal] = v;
      equal += v <= pivot;
    }
    if (k < equal) return pivot;
    lo = equal;
  }
  std::sort(a + lo, a + hi);
  return a[k];
}

const PassTable* passTableFor(cpu::CpuLevel level) {
  switch (level) {
    case cpu::CpuLevel::kPortable:
      return &kBaseline;
#ifdef VG_MATCH_PASSES_AVX2
    case cpu::CpuLevel::kAvx2:
      return cpu::runs(level) ? &kAvx2 : nullptr;
#endif
    default:
      return nullptr;
  }
}

const PassTable& passes() {
  static const PassTable& table = *cpu::selectKernel(passTableFor, cpu::activeLevel());
  return table;
}

}  // namespace passes
}  // namespace visual_gyro
