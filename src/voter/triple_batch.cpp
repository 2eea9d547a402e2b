// The triple solver in eight AVX lanes. The scalar solver is a chain of dependent square roots and
// divisions (one-sided Jacobi), so one triple at a time leaves most of the core idle; eight triples
// per instruction fill it. Each lane replays the scalar code's operations in the same order, in
// IEEE single precision without fused multiply-add (neither build contracts: no FMA is enabled), so
// the results are the scalar solver's bit for bit. The scalar code's branches become lane masks: a
// lane whose triple is rejected keeps computing but its results are dropped, and a Jacobi rotation
// a lane skips is blended away. Sweeps continue while any lane still rotates; for a lane that
// already found every pair orthogonal, a further sweep finds the same and changes nothing.
#include "triple_batch.h"

#include "../core/cpu_features.h"  // header-only: the CPU level every kernel is chosen by

// Without FMA enabled for the whole file: with it, the compiler may fuse the scalar solver's
// multiplications and additions, which the lanes do not reproduce; the scalar solver then runs.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__FMA__)
#include <immintrin.h>
#define VG_TRIPLE_BATCH 1
#endif

namespace visual_gyro {
namespace hyp {

namespace {

// The scalar solver, triple by triple.
void solveOneByOne(const Vec3f* prev, const Vec3f* cur, const uint32_t (*idx)[3], int count, const TripleOptions& opt,
                   int32_t* status, Mat3f* R) {
  for (int k = 0; k < count; ++k) {
    const Vec3f p[3] = {prev[idx[k][0]], prev[idx[k][1]], prev[idx[k][2]]};
    const Vec3f c[3] = {cur[idx[k][0]], cur[idx[k][1]], cur[idx[k][2]]};
    status[k] = solveTripleRotation(p, c, opt, &R[k]);
  }
}

}  // namespace

#ifdef VG_TRIPLE_BATCH

namespace {

#define VG_AVX __attribute__((target("avx"))) inline

// Eight floats; comparisons give lane masks (all bits set where true).
struct F8 {
  __m256 v;
};

VG_AVX F8 broadcast(float x) { return F8{_mm256_set1_ps(x)}; }
VG_AVX F8 operator+(F8 a, F8 b) { return F8{_mm256_add_ps(a.v, b.v)}; }
VG_AVX F8 operator-(F8 a, F8 b) { return F8{_mm256_sub_ps(a.v, b.v)}; }
VG_AVX F8 operator*(F8 a, F8 b) { return F8{_mm256_mul_ps(a.v, b.v)}; }
VG_AVX F8 operator/(F8 a, F8 b) { return F8{_mm256_div_ps(a.v, b.v)}; }
VG_AVX F8 operator&(F8 a, F8 b) { return F8{_mm256_and_ps(a.v, b.v)}; }
VG_AVX F8 operator|(F8 a, F8 b) { return F8{_mm256_or_ps(a.v, b.v)}; }
VG_AVX F8 sqrt8(F8 a) { return F8{_mm256_sqrt_ps(a.v)}; }
VG_AVX F8 abs8(F8 a) { return F8{_mm256_andnot_ps(_mm256_set1_ps(-0.f), a.v)}; }
// mask ? a : b
VG_AVX F8 select(F8 mask, F8 a, F8 b) { return F8{_mm256_blendv_ps(b.v, a.v, mask.v)}; }
VG_AVX F8 isNan(F8 a) { return F8{_mm256_cmp_ps(a.v, a.v, _CMP_UNORD_Q)}; }
// fminf and fmaxf, NaN rules included (a NaN operand yields the other one): min_ps(b, a) returns
// a when either is NaN, which is right when only b is; a NaN a is replaced by b.
VG_AVX F8 fmin8(F8 a, F8 b) { return select(isNan(a), b, F8{_mm256_min_ps(b.v, a.v)}); }
VG_AVX F8 fmax8(F8 a, F8 b) { return select(isNan(a), b, F8{_mm256_max_ps(b.v, a.v)}); }
// The comparisons as the scalar code writes them; NaN compares false, its negation true.
VG_AVX F8 lessEqual(F8 a, F8 b) { return F8{_mm256_cmp_ps(a.v, b.v, _CMP_LE_OQ)}; }
VG_AVX F8 greater(F8 a, F8 b) { return F8{_mm256_cmp_ps(a.v, b.v, _CMP_GT_OQ)}; }
VG_AVX F8 less(F8 a, F8 b) { return F8{_mm256_cmp_ps(a.v, b.v, _CMP_LT_OQ)}; }
VG_AVX F8 greaterEqual(F8 a, F8 b) { return F8{_mm256_cmp_ps(a.v, b.v, _CMP_GE_OQ)}; }
VG_AVX F8 equal(F8 a, F8 b) { return F8{_mm256_cmp_ps(a.v, b.v, _CMP_EQ_OQ)}; }
VG_AVX F8 notGreaterEqual(F8 a, F8 b) { return F8{_mm256_cmp_ps(a.v, b.v, _CMP_NGE_UQ)}; }
VG_AVX F8 notGreater(F8 a, F8 b) { return F8{_mm256_cmp_ps(a.v, b.v, _CMP_NGT_UQ)}; }
VG_AVX F8 andNot(F8 mask, F8 a) { return F8{_mm256_andnot_ps(mask.v, a.v)}; }  // a & ~mask
VG_AVX int bits(F8 mask) { return _mm256_movemask_ps(mask.v); }

// Vec3f of eight lanes, with the scalar helpers' operation order.
struct V8 {
  F8 x, y, z;
};

VG_AVX V8 operator+(const V8& a, const V8& b) { return V8{a.x + b.x, a.y + b.y, a.z + b.z}; }
VG_AVX V8 operator-(const V8& a, const V8& b) { return V8{a.x - b.x, a.y - b.y, a.z - b.z}; }
VG_AVX V8 operator*(F8 s, const V8& a) { return V8{s * a.x, s * a.y, s * a.z}; }
VG_AVX F8 dot(const V8& a, const V8& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
VG_AVX V8 cross(const V8& a, const V8& b) {
  return V8{a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
VG_AVX F8 norm(const V8& a) { return sqrt8(dot(a, a)); }
VG_AVX V8 select(F8 mask, const V8& a, const V8& b) {
  return V8{select(mask, a.x, b.x), select(mask, a.y, b.y), select(mask, a.z, b.z)};
}

// The bearings of eight triples, lane by lane: bearing i of lane k is (x[i][k], y[i][k], z[i][k]).
struct TripleLanes {
  alignas(32) float x[3][kTripleBatch];
  alignas(32) float y[3][kTripleBatch];
  alignas(32) float z[3][kTripleBatch];
};

// Fills the lanes with the triples of hypotheses which[0..count) (count <= kTripleBatch), the
// remaining lanes with copies of the first, whose results are dropped.
void fillLanes(const Vec3f* bearings, const uint32_t (*idx)[3], const int* which, int count, TripleLanes* lanes) {
  for (int k = 0; k < kTripleBatch; ++k) {
    const uint32_t* triple = idx[which[k < count ? k : 0]];
    for (int i = 0; i < 3; ++i) {
      const Vec3f& b = bearings[triple[i]];
      lanes->x[i][k] = b.x;
      lanes->y[i][k] = b.y;
      lanes->z[i][k] = b.z;
    }
  }
}

// Bearing i of the lanes.
VG_AVX V8 load(const TripleLanes& lanes, int i) {
  return V8{F8{_mm256_load_ps(lanes.x[i])}, F8{_mm256_load_ps(lanes.y[i])}, F8{_mm256_load_ps(lanes.z[i])}};
}

// Gives the lanes of `open` that `fails` status `why` (in the lanes of *status) and closes them;
// false when none is left open.
VG_AVX bool reject(F8 fails, int32_t why, F8* open, F8* status) {
  const F8 newly = *open & fails;
  *status = select(newly, F8{_mm256_castsi256_ps(_mm256_set1_epi32(why))}, *status);
  *open = andNot(fails, *open);
  return bits(*open) != 0;
}

// The lanes' statuses into status[].
VG_AVX void storeStatus(F8 lanes, int32_t status[kTripleBatch]) {
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(status), _mm256_castps_si256(lanes.v));
}

VG_AVX void swapTriplets(F8 swap, F8* sa, V8* ha, V8* va, F8* sb, V8* hb, V8* vb) {
  const F8 s = *sa;
  const V8 h = *ha, v = *va;
  *sa = select(swap, *sb, *sa);
  *sb = select(swap, s, *sb);
  *ha = select(swap, *hb, *ha);
  *hb = select(swap, h, *hb);
  *va = select(swap, *vb, *va);
  *vb = select(swap, v, *vb);
}

// Arun's H = sum p q^T of the lanes' triples (p = current, q = previous bearings), by columns.
VG_AVX void crossCovariance(const V8 pr[3], const V8 cu[3], const TripleOptions& opt, V8 h[3]) {
  V8 p[3] = {cu[0], cu[1], cu[2]};  // source points (rotated by R)
  V8 q[3] = {pr[0], pr[1], pr[2]};  // target points
  if (opt.centroid_subtraction) {
    const F8 third = broadcast(1.f / 3.f);
    const V8 cp = third * (p[0] + p[1] + p[2]);
    const V8 cq = third * (q[0] + q[1] + q[2]);
    for (int i = 0; i < 3; ++i) {
      p[i] = p[i] - cp;
      q[i] = q[i] - cq;
    }
  }
  h[0] = V8{p[0].x * q[0].x + p[1].x * q[1].x + p[2].x * q[2].x, p[0].y * q[0].x + p[1].y * q[1].x + p[2].y * q[2].x,
            p[0].z * q[0].x + p[1].z * q[1].x + p[2].z * q[2].x};
  h[1] = V8{p[0].x * q[0].y + p[1].x * q[1].y + p[2].x * q[2].y, p[0].y * q[0].y + p[1].y * q[1].y + p[2].y * q[2].y,
            p[0].z * q[0].y + p[1].z * q[1].y + p[2].z * q[2].y};
  h[2] = V8{p[0].x * q[0].z + p[1].x * q[1].z + p[2].x * q[2].z, p[0].y * q[0].z + p[1].y * q[1].z + p[2].y * q[2].z,
            p[0].z * q[0].z + p[1].z * q[1].z + p[2].z * q[2].z};
}

// The tests solveTripleRotation makes before its SVD, for the lanes' triples: the status of each
// rejected lane is written, and the mask of the lanes that pass (bit k: lane k) returned.
__attribute__((target("avx"))) int screenAvx(const TripleLanes& prev, const TripleLanes& cur, const TripleOptions& opt,
                                              int32_t status[kTripleBatch]) {
  const V8 pr[3] = {load(prev, 0), load(prev, 1), load(prev, 2)};
  const V8 cu[3] = {load(cur, 0), load(cur, 1), load(cur, 2)};
  F8 open = F8{_mm256_castsi256_ps(_mm256_set1_epi32(-1))};
  F8 why = broadcast(0.f);  // kTripleOk
  const V8 dp01 = pr[1] - pr[0], dp02 = pr[2] - pr[0], dp12 = pr[2] - pr[1];
  const V8 dc01 = cu[1] - cu[0], dc02 = cu[2] - cu[0], dc12 = cu[2] - cu[1];
  const F8 lp01 = norm(dp01), lp02 = norm(dp02), lp12 = norm(dp12);
  const F8 lc01 = norm(dc01), lc02 = norm(dc02), lc12 = norm(dc12);
  const F8 shortest = fmin8(fmin8(lp01, lp02), fmin8(lp12, fmin8(lc01, fmin8(lc02, lc12))));
  bool left = reject(notGreaterEqual(shortest, broadcast(opt.min_separation)), kTripleRepeated, &open, &why);
  if (left) {
    const F8 area = broadcast(0.5f) * fmin8(norm(cross(dp01, dp02)), norm(cross(dc01, dc02)));
    left = reject(notGreaterEqual(area, broadcast(opt.min_triangle_area)), kTripleCollinear, &open, &why);
  }
  if (left && opt.max_angle_change > 0.f) {
    const F8 change = fmax8(abs8(lp01 - lc01), fmax8(abs8(lp02 - lc02), abs8(lp12 - lc12)));
    left = reject(greater(change, broadcast(opt.max_angle_change)), kTripleInconsistent, &open, &why);
  }
  if (left && !opt.centroid_subtraction) {
    V8 h[3];
    crossCovariance(pr, cu, opt, h);
    const F8 detH = dot(h[0], cross(h[1], h[2]));
    reject(notGreater(detH, broadcast(0.f)), kTripleReflection, &open, &why);
  }
  storeStatus(why, status);
  return bits(open);
}

// The rest of solveTripleRotation for lanes that passed screenAvx: one-sided Jacobi, the ordering
// of the singular values, the rank test and R.
__attribute__((target("avx"))) void solveScreenedAvx(const TripleLanes& prev, const TripleLanes& cur,
                                                      const TripleOptions& opt, int32_t status[kTripleBatch],
                                                      Mat3f R[kTripleBatch]) {
  const V8 pr[3] = {load(prev, 0), load(prev, 1), load(prev, 2)};
  const V8 cu[3] = {load(cur, 0), load(cur, 1), load(cur, 2)};
  F8 open = F8{_mm256_castsi256_ps(_mm256_set1_epi32(-1))};
  const F8 zero = broadcast(0.f), one = broadcast(1.f);
  V8 h[3];
  crossCovariance(pr, cu, opt, h);

  V8 v[3] = {V8{one, zero, zero}, V8{zero, one, zero}, V8{zero, zero, one}};
  const F8 tiny = broadcast(1e-7f), two = broadcast(2.f), minus_one = broadcast(-1.f);
  for (int sweep = 0; sweep < 6; ++sweep) {
    F8 rotated = zero;
    for (int pair = 0; pair < 3; ++pair) {
      const int i = pair == 2 ? 1 : 0;
      const int j = pair == 0 ? 1 : 2;
      const F8 alpha = dot(h[i], h[i]);
      const F8 beta = dot(h[j], h[j]);
      const F8 gamma = dot(h[i], h[j]);
      const F8 skip = lessEqual(abs8(gamma), tiny * sqrt8(alpha * beta)) | equal(gamma, zero);
      if (bits(skip) == 0xFF) continue;
      rotated = rotated | andNot(skip, open);
      const F8 zeta = (beta - alpha) / (two * gamma);
      const F8 t = select(greaterEqual(zeta, zero), one, minus_one) / (abs8(zeta) + sqrt8(one + zeta * zeta));
      const F8 c = one / sqrt8(one + t * t);
      const F8 s = c * t;
      const V8 hi = h[i], hj = h[j], vi = v[i], vj = v[j];
      h[i] = select(skip, hi, c * hi - s * hj);
      h[j] = select(skip, hj, s * hi + c * hj);
      v[i] = select(skip, vi, c * vi - s * vj);
      v[j] = select(skip, vj, s * vi + c * vj);
    }
    if (bits(rotated) == 0) break;
  }
  F8 s0 = norm(h[0]), s1 = norm(h[1]), s2 = norm(h[2]);
  V8 h0 = h[0], h1 = h[1], h2 = h[2];
  V8 v0 = v[0], v1 = v[1], v2 = v[2];
  swapTriplets(greater(s1, s0), &s0, &h0, &v0, &s1, &h1, &v1);
  swapTriplets(greater(s2, s0), &s0, &h0, &v0, &s2, &h2, &v2);
  swapTriplets(greater(s2, s1), &s1, &h1, &v1, &s2, &h2, &v2);
  const F8 degenerate = notGreater(s1, tiny * s0) | notGreater(s0, zero);
  F8 why = broadcast(0.f);  // kTripleOk
  const bool any_left = reject(degenerate, kTripleCollinear, &open, &why);
  storeStatus(why, status);
  if (!any_left) return;
  const V8 u0 = (one / s0) * h0;
  V8 u1 = h1 - dot(u0, h1) * u0;
  u1 = (one / norm(u1)) * u1;
  const V8 u2 = cross(u0, u1);
  const F8 detV = dot(v0, cross(v1, v2));
  v2 = select(less(detV, zero), minus_one * v2, v2);
  const F8 m[9] = {v0.x * u0.x + v1.x * u1.x + v2.x * u2.x, v0.x * u0.y + v1.x * u1.y + v2.x * u2.y,
                   v0.x * u0.z + v1.x * u1.z + v2.x * u2.z, v0.y * u0.x + v1.y * u1.x + v2.y * u2.x,
                   v0.y * u0.y + v1.y * u1.y + v2.y * u2.y, v0.y * u0.z + v1.y * u1.z + v2.y * u2.z,
                   v0.z * u0.x + v1.z * u1.x + v2.z * u2.x, v0.z * u0.y + v1.z * u1.y + v2.z * u2.y,
                   v0.z * u0.z + v1.z * u1.z + v2.z * u2.z};
  float lanes[9][kTripleBatch];
  for (int e = 0; e < 9; ++e) _mm256_storeu_ps(lanes[e], m[e].v);
  const int ok = bits(open);
  for (int k = 0; k < kTripleBatch; ++k) {
    if (!(ok & (1 << k))) continue;
    for (int e = 0; e < 9; ++e) R[k].m[e] = lanes[e][k];
  }
}

#undef VG_AVX

// High (hi) and low (lo) 32 bits of the 64-bit products m * c of the lanes: those of the even lanes
// come from one multiply, those of the odd lanes from a second on the lanes shifted down.
__attribute__((target("avx2"))) inline void multiply(__m256i m, __m256i c, __m256i* hi, __m256i* lo) {
  const __m256i even = _mm256_mul_epu32(m, c);
  const __m256i odd = _mm256_mul_epu32(_mm256_srli_epi64(m, 32), _mm256_srli_epi64(c, 32));
  *lo = _mm256_blend_epi32(even, _mm256_slli_epi64(odd, 32), 0xAA);
  *hi = _mm256_blend_epi32(_mm256_srli_epi64(even, 32), odd, 0xAA);
}

// Philox4x32-10 (philox4x32) for eight counters at once; the first three words of each block.
__attribute__((target("avx2"))) void philoxAvx2(__m256i c0, __m256i c1, __m256i c2, __m256i c3, uint32_t key_lo,
                                                uint32_t key_hi, __m256i out[3]) {
  const __m256i m0 = _mm256_set1_epi32(static_cast<int>(0xD2511F53u));
  const __m256i m1 = _mm256_set1_epi32(static_cast<int>(0xCD9E8D57u));
  __m256i k0 = _mm256_set1_epi32(static_cast<int>(key_lo)), k1 = _mm256_set1_epi32(static_cast<int>(key_hi));
  const __m256i step0 = _mm256_set1_epi32(static_cast<int>(0x9E3779B9u));
  const __m256i step1 = _mm256_set1_epi32(static_cast<int>(0xBB67AE85u));
  for (int round = 0; round < 10; ++round) {
    __m256i hi0, lo0, hi1, lo1;
    multiply(m0, c0, &hi0, &lo0);
    multiply(m1, c2, &hi1, &lo1);
    c0 = _mm256_xor_si256(_mm256_xor_si256(hi1, c1), k0);
    c1 = lo1;
    c2 = _mm256_xor_si256(_mm256_xor_si256(hi0, c3), k1);
    c3 = lo0;
    k0 = _mm256_add_epi32(k0, step0);
    k1 = _mm256_add_epi32(k1, step1);
  }
  out[0] = c0;
  out[1] = c1;
  out[2] = c2;
}

// drawTriples for whole batches of eight; returns how many it drew.
__attribute__((target("avx2"))) int drawBatchesAvx2(uint64_t seed, uint32_t first, int count, uint32_t n,
                                                    uint32_t (*idx)[3]) {
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i zero = _mm256_setzero_si256();
  const __m256i word2 = _mm256_set1_epi32(static_cast<int>(kTripleCounterWord2));
  const __m256i word3 = _mm256_set1_epi32(static_cast<int>(kTripleCounterWord3));
  int k = 0;
  for (; k + kTripleBatch <= count; k += kTripleBatch) {
    __m256i r[3];
    const __m256i counter = _mm256_add_epi32(_mm256_set1_epi32(static_cast<int>(first + k)), lane);
    philoxAvx2(counter, zero, word2, word3, static_cast<uint32_t>(seed), static_cast<uint32_t>(seed >> 32), r);
    uint32_t words[3][kTripleBatch];
    for (int w = 0; w < 3; ++w) _mm256_storeu_si256(reinterpret_cast<__m256i*>(words[w]), r[w]);
    for (int l = 0; l < kTripleBatch; ++l) drawFromWords(words[0][l], words[1][l], words[2][l], n, idx[k + l]);
  }
  return k;
}

bool drawBatchAvailable() {
  static const bool available = cpu::runs(cpu::CpuLevel::kAvx2);
  return available;
}

}  // namespace

bool tripleBatchAvailable() {
  static const bool available = cpu::runs(cpu::CpuLevel::kAvx);
  return available;
}

void drawTriples(uint64_t seed, uint32_t first, int count, uint32_t n, uint32_t (*idx)[3]) {
  const int drawn = drawBatchAvailable() ? drawBatchesAvx2(seed, first, count, n, idx) : 0;
  for (int k = drawn; k < count; ++k) drawTriple(seed, first + static_cast<uint32_t>(k), n, idx[k]);
}

void solveTriples(const Vec3f* prev, const Vec3f* cur, const uint32_t (*idx)[3], int count, const TripleOptions& opt,
                  int32_t* status, Mat3f* R) {
  if (!tripleBatchAvailable()) {
    solveOneByOne(prev, cur, idx, count, opt, status, R);
    return;
  }
  // Most triples of a narrow vote fail the cheap tests; the SVD lanes are filled with those that
  // pass, so that no lane of the expensive part is wasted on a rejected triple.
  TripleLanes screen_prev, screen_cur, solve_prev, solve_cur;
  int32_t screen_status[kTripleBatch], solve_status[kTripleBatch];
  Mat3f solve_R[kTripleBatch];
  int which[kTripleBatch], passed[kTripleBatch];
  int queued = 0;
  auto solveQueued = [&]() {
    fillLanes(prev, idx, passed, queued, &solve_prev);
    fillLanes(cur, idx, passed, queued, &solve_cur);
    solveScreenedAvx(solve_prev, solve_cur, opt, solve_status, solve_R);
    for (int k = 0; k < queued; ++k) {
      status[passed[k]] = solve_status[k];
      if (solve_status[k] == kTripleOk) R[passed[k]] = solve_R[k];
    }
    queued = 0;
  };
  for (int first = 0; first < count; first += kTripleBatch) {
    const int lanes = count - first < kTripleBatch ? count - first : kTripleBatch;
    for (int k = 0; k < lanes; ++k) which[k] = first + k;
    fillLanes(prev, idx, which, lanes, &screen_prev);
    fillLanes(cur, idx, which, lanes, &screen_cur);
    const int pass = screenAvx(screen_prev, screen_cur, opt, screen_status);
    for (int k = 0; k < lanes; ++k) {
      if (!(pass & (1 << k))) {
        status[first + k] = screen_status[k];
        continue;
      }
      passed[queued++] = first + k;
      if (queued == kTripleBatch) solveQueued();
    }
  }
  if (queued > 0) solveQueued();
}

#else  // no x86-64 SIMD

bool tripleBatchAvailable() { return false; }

void drawTriples(uint64_t seed, uint32_t first, int count, uint32_t n, uint32_t (*idx)[3]) {
  for (int k = 0; k < count; ++k) drawTriple(seed, first + static_cast<uint32_t>(k), n, idx[k]);
}

void solveTriples(const Vec3f* prev, const Vec3f* cur, const uint32_t (*idx)[3], int count, const TripleOptions& opt,
                  int32_t* status, Mat3f* R) {
  solveOneByOne(prev, cur, idx, count, opt, status, R);
}

#endif

}  // namespace hyp
}  // namespace visual_gyro
