// Hamming-distance search kernels; see hamming_kernels.h. Every kernel is one body inlined into a
// function per instruction set (target attributes, no -march flags), so the results agree bit for bit.
#include "hamming_kernels.h"
#include "cpu_features.h"

#include <algorithm>
#include <cmath>
#include <limits>
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace visual_gyro {
namespace hamming {

namespace {

/// No distance yet (a row or column not compared).
constexpr int kNone = std::numeric_limits<int>::max();

/// Brute-force search of every previous descriptor against every current one in a single pass:
/// for each row the best and second-best distance, for each column the best row (for the
/// cross-check). Always inlined, so it is compiled once per instruction set into the callers below
/// (baseline x86-64 has no popcnt instruction and the software popcount is several times slower).
__attribute__((always_inline)) inline void bruteForceKernel(const BriefDescriptor* prev, int n_prev,
                                                            const BriefDescriptor* cur, int n_cur,
                                                            const SearchTables& t) {
  int* row_best = t.row_best;
  int* row_best_d = t.row_best_d;
  int* row_second_d = t.row_second_d;
  int* col_best = t.col_best;
  int* col_best_d = t.col_best_d;
  for (int j = 0; j < n_cur; ++j) {
    col_best[j] = kNoMatch;
    col_best_d[j] = kNone;
  }
  for (int i = 0; i < n_prev; ++i) {
    const uint64_t a0 = prev[i][0], a1 = prev[i][1], a2 = prev[i][2], a3 = prev[i][3];
    int best = kNone, second = kNone;
    int best_j = kNoMatch;
    for (int j = 0; j < n_cur; ++j) {
      const BriefDescriptor& b = cur[j];
      const int d = __builtin_popcountll(a0 ^ b[0]) + __builtin_popcountll(a1 ^ b[1]) +
                    __builtin_popcountll(a2 ^ b[2]) + __builtin_popcountll(a3 ^ b[3]);
      if (d < second) {
        if (d < best) {
          second = best;
          best = d;
          best_j = j;
        } else {
          second = d;
        }
      }
      if (d < col_best_d[j]) {
        col_best_d[j] = d;
        col_best[j] = i;
      }
    }
    row_best[i] = best_j;
    row_best_d[i] = best;
    row_second_d[i] = second;
  }
}

void bruteForcePortable(const BriefDescriptor* prev, int n_prev, const BriefDescriptor* cur, int n_cur,
                        const SearchTables& tables) {
  bruteForceKernel(prev, n_prev, cur, n_cur, tables);
}

#if defined(__x86_64__) && defined(__GNUC__)
// Same kernel with the popcnt instruction enabled; used only when the CPU reports it (runtime
// dispatch, so the binary still runs on any x86-64 and no -march flag is needed).
__attribute__((target("popcnt"))) void bruteForcePopcnt(const BriefDescriptor* prev, int n_prev,
                                                        const BriefDescriptor* cur, int n_cur,
                                                        const SearchTables& tables) {
  bruteForceKernel(prev, n_prev, cur, n_cur, tables);
}
#endif

// Guided search: previous descriptor i against the current descriptors in the grid cells its
// window overlaps, kept when within the window's radius. The current keypoints are stored in
// row-major cell order, so the cells of one grid row that a window spans are one contiguous run:
// one position test per grid row, no per-cell overhead. First the candidates inside the circle
// are listed (the runs of whole cells also hold many outside it), then distances and bookkeeping
// run on that list only. Both steps are policies, so each instruction set gets its own.

/// Appends to `inside` (from *count on) the indices k in [begin, end) of the grid's points within
/// sqrt(r2) of (px, py), in increasing order, one at a time without a branch (whether a candidate
/// is inside is unpredictable).
struct ScalarPositionTest {
  __attribute__((always_inline)) void operator()(const cv::Point2f* points, int begin, int end, float px,
                                                 float py, float r2, int* inside, int* count) const {
    int n = *count;
    for (int k = begin; k < end; ++k) {
      const float dx = points[k].x - px, dy = points[k].y - py;
      inside[n] = k;
      n += !(dx * dx + dy * dy > r2);
    }
    *count = n;
  }
};

/// Row i's distances to its listed candidates and the bookkeeping of bruteForceKernel (row best
/// and second best, column best), one candidate at a time. `inside` holds n increasing column
/// indices (and kGuidedPad more places of room).
struct ScalarCandidatePass {
  __attribute__((always_inline)) void operator()(const BriefDescriptor& a, int i, const int* inside, int n,
                                                 const BriefDescriptor* descriptors, int* col_best,
                                                 int* col_best_d, int* best_out, int* second_out,
                                                 int* best_k_out) const {
    int best = kNone, second = kNone, best_k = kNoMatch;
    const uint64_t a0 = a[0], a1 = a[1], a2 = a[2], a3 = a[3];
    for (int m = 0; m < n; ++m) {
      const int k = inside[m];
      const BriefDescriptor& b = descriptors[k];
      const int d = __builtin_popcountll(a0 ^ b[0]) + __builtin_popcountll(a1 ^ b[1]) +
                    __builtin_popcountll(a2 ^ b[2]) + __builtin_popcountll(a3 ^ b[3]);
      // Branch-free bookkeeping (the same result as the branches in bruteForceKernel: the first
      // of equal distances stays best): which candidate wins is data-dependent and about as
      // unpredictable as a coin, so compares and selects beat branches here.
      second = std::min(second, std::max(best, d));
      best_k = d < best ? k : best_k;
      best = std::min(best, d);
      const int old_d = col_best_d[k];
      col_best[k] = d < old_d ? i : col_best[k];
      col_best_d[k] = std::min(old_d, d);
    }
    *best_out = best;
    *second_out = second;
    *best_k_out = best_k;
  }
};

template <class PositionTest, class CandidatePass>
__attribute__((always_inline)) inline void guidedKernelBody(const BriefDescriptor* prev, int n_prev,
                                                            const cv::Point2f* predicted, const float* radii,
                                                            const GuidedGrid& grid, const SearchTables& t,
                                                            PositionTest position_test,
                                                            CandidatePass candidate_pass) {
  for (int k = 0; k < grid.n; ++k) {
    t.col_best[k] = kNoMatch;
    t.col_best_d[k] = kNone;
  }
  const float inv_cell = 1.0f / grid.cell_size;
  for (int i = 0; i < n_prev; ++i) {
    int best = kNone, second = kNone, best_k = kNoMatch;
    const float r = radii[i];
    if (r >= 0.0f) {
      const float px = predicted[i].x, py = predicted[i].y, r2 = r * r;
      const int cx0 = std::max(0, static_cast<int>(std::floor((px - r) * inv_cell)));
      const int cx1 = std::min(grid.cols - 1, static_cast<int>(std::floor((px + r) * inv_cell)));
      const int cy0 = std::max(0, static_cast<int>(std::floor((py - r) * inv_cell)));
      const int cy1 = std::min(grid.rows - 1, static_cast<int>(std::floor((py + r) * inv_cell)));
      int n_inside = 0;
      for (int cy = cy0; cy <= cy1 && cx0 <= cx1; ++cy) {
        position_test(grid.points, grid.start[cy * grid.cols + cx0], grid.start[cy * grid.cols + cx1 + 1], px,
                      py, r2, grid.inside, &n_inside);
      }
      candidate_pass(prev[i], i, grid.inside, n_inside, grid.descriptors, t.col_best, t.col_best_d, &best,
                     &second, &best_k);
    }
    t.row_best[i] = best_k;
    t.row_best_d[i] = best;
    t.row_second_d[i] = second;
  }
}

void guidedPortable(const BriefDescriptor* prev, int n_prev, const cv::Point2f* predicted, const float* radii,
                    const GuidedGrid& grid, const SearchTables& tables) {
  guidedKernelBody(prev, n_prev, predicted, radii, grid, tables, ScalarPositionTest(), ScalarCandidatePass());
}

#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("popcnt"))) void guidedPopcnt(const BriefDescriptor* prev, int n_prev,
                                                    const cv::Point2f* predicted, const float* radii,
                                                    const GuidedGrid& grid, const SearchTables& tables) {
  guidedKernelBody(prev, n_prev, predicted, radii, grid, tables, ScalarPositionTest(), ScalarCandidatePass());
}

/// For each 8-bit mask, the positions of its set bits in increasing order (the rest 0): the
/// permutation that packs the selected lanes of an 8-lane vector to its front.
struct PackTable {
  alignas(32) int32_t lanes[256][8];
  PackTable() {
    for (int mask = 0; mask < 256; ++mask) {
      int n = 0;
      for (int lane = 0; lane < 8; ++lane)
        if (mask & (1 << lane)) lanes[mask][n++] = lane;
      for (; n < 8; ++n) lanes[mask][n] = 0;
    }
  }
};
const PackTable kPackTable;

/// ScalarPositionTest eight candidates at a time: the points' x and y deinterleaved, the squared
/// distances compared in one instruction, and the indices of those inside packed to the front of
/// a vector stored at the end of the list (the next store overwrites the lanes beyond the count).
/// Reads up to 7 points past `end` and writes up to 7 indices past the count: matchGuided pads
/// both arrays by kGuidedPad. A function of its own (called once per grid row of a window):
/// AVX2 code cannot be inlined into the kernel's shared body.
__attribute__((target("avx2"))) void positionTestAvx2(const cv::Point2f* points, int begin, int end, float px,
                                                    float py, float r2, int* inside, int* count) {
  const __m256 vx = _mm256_set1_ps(px), vy = _mm256_set1_ps(py), vr2 = _mm256_set1_ps(r2);
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i last = _mm256_set1_epi32(end - 1);
  int n = *count;
  for (int k = begin; k < end; k += 8) {
    const float* xy = &points[k].x;
    const __m256 a = _mm256_loadu_ps(xy), b = _mm256_loadu_ps(xy + 8);
    // The shuffle gives x0 x1 x4 x5 | x2 x3 x6 x7; the 64-bit permute restores x0 .. x7.
    const __m256 x = _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(a, b, 0x88)), 0xD8));
    const __m256 y = _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(a, b, 0xDD)), 0xD8));
    const __m256 dx = _mm256_sub_ps(x, vx), dy = _mm256_sub_ps(y, vy);
    // The scalar test's rounding: each product rounded, then the sum (no fused multiply-add: the
    // target does not enable FMA, so the compiler cannot contract these).
    const __m256 d2 = _mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy));
    const __m256i index = _mm256_add_epi32(_mm256_set1_epi32(k), lane);
    // !(d2 > r2), as the scalar test (true for NaN too), and only lanes before `end`.
    const __m256 outside = _mm256_cmp_ps(d2, vr2, _CMP_GT_OQ);
    const int in_run = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(index, last))) ^ 0xFF;
    const int mask = (_mm256_movemask_ps(outside) ^ 0xFF) & in_run;
    const __m256i packed = _mm256_permutevar8x32_epi32(
        index, _mm256_load_si256(reinterpret_cast<const __m256i*>(kPackTable.lanes[mask])));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(inside + n), packed);
    n += __builtin_popcount(static_cast<unsigned>(mask));
  }
  *count = n;
}

struct Avx2PositionTest {
  __attribute__((always_inline)) void operator()(const cv::Point2f* points, int begin, int end, float px, float py,
                                                 float r2, int* inside, int* count) const {
    if (begin < end) positionTestAvx2(points, begin, end, px, py, r2, inside, count);
  }
};

// The popcnt kernel with the position test eight candidates at a time; used only when the CPU
// reports AVX2 (which every CPU with it pairs with popcnt).
__attribute__((target("avx2,popcnt"))) void guidedAvx2(const BriefDescriptor* prev, int n_prev,
                                                       const cv::Point2f* predicted, const float* radii,
                                                       const GuidedGrid& grid, const SearchTables& tables) {
  guidedKernelBody(prev, n_prev, predicted, radii, grid, tables, Avx2PositionTest(), ScalarCandidatePass());
}

#define VISUAL_GYRO_AVX512_TARGET "avx2,popcnt,avx512f,avx512vl,avx512vpopcntdq"
// GCC 12's AVX-512 headers make their "undefined" vectors by self-initialisation, which
// -Wmaybe-uninitialized reports wherever such an intrinsic is inlined.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

/// ScalarPositionTest sixteen candidates at a time: the indices of those inside compressed to the
/// front of a vector stored at the end of the list. Reads up to 15 points past `end` and writes
/// up to 15 indices past the count (kGuidedPad).
__attribute__((target(VISUAL_GYRO_AVX512_TARGET))) void positionTestAvx512(
    const cv::Point2f* points, int begin, int end, float px, float py, float r2, int* inside, int* count) {
  const __m512 vx = _mm512_set1_ps(px), vy = _mm512_set1_ps(py), vr2 = _mm512_set1_ps(r2);
  const __m512i lane = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  const __m512i even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
  const __m512i odd = _mm512_add_epi32(even, _mm512_set1_epi32(1));
  int n = *count;
  for (int k = begin; k < end; k += 16) {
    const float* xy = &points[k].x;
    const __m512 a = _mm512_loadu_ps(xy), b = _mm512_loadu_ps(xy + 16);
    const __m512 x = _mm512_permutex2var_ps(a, even, b), y = _mm512_permutex2var_ps(a, odd, b);
    const __m512 dx = _mm512_sub_ps(x, vx), dy = _mm512_sub_ps(y, vy);
    // Each product rounded, then the sum, as the scalar test: this file is compiled without
    // floating-point contraction, so no fused multiply-add replaces them.
    const __m512 d2 = _mm512_add_ps(_mm512_mul_ps(dx, dx), _mm512_mul_ps(dy, dy));
    const int left = end - k;
    const __mmask16 in_run = left >= 16 ? __mmask16(0xFFFF) : __mmask16((1u << left) - 1u);
    // !(d2 > r2), as the scalar test (true for NaN too), and only lanes before `end`.
    const __mmask16 mask = _mm512_kandn(_mm512_cmp_ps_mask(d2, vr2, _CMP_GT_OQ), in_run);
    const __m512i index = _mm512_add_epi32(_mm512_set1_epi32(k), lane);
    _mm512_storeu_si512(inside + n, _mm512_maskz_compress_epi32(mask, index));
    n += __builtin_popcount(static_cast<unsigned>(mask));
  }
  *count = n;
}

struct Avx512PositionTest {
  __attribute__((always_inline)) void operator()(const cv::Point2f* points, int begin, int end, float px, float py,
                                                 float r2, int* inside, int* count) const {
    if (begin < end) positionTestAvx512(points, begin, end, px, py, r2, inside, count);
  }
};

/// Smallest of eight lanes.
__attribute__((target(VISUAL_GYRO_AVX512_TARGET), always_inline)) inline int minLane(__m256i v) {
  __m128i m = _mm_min_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
  m = _mm_min_epi32(m, _mm_shuffle_epi32(m, 0x4E));
  m = _mm_min_epi32(m, _mm_shuffle_epi32(m, 0xB1));
  return _mm_cvtsi128_si32(m);
}

/// The bits in which descriptors[low] and descriptors[high] (the low and high halves) differ from
/// `a` (in both halves), counted per 64-bit word. Always inlined: a lambda would not take its
/// caller's AVX-512 target.
__attribute__((target(VISUAL_GYRO_AVX512_TARGET), always_inline)) inline __m512i wordCounts(
    const BriefDescriptor* descriptors, int low, int high, __m512i a) {
  const __m256i lo = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(descriptors[low].data()));
  const __m256i hi = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(descriptors[high].data()));
  return _mm512_popcnt_epi64(_mm512_xor_si512(_mm512_inserti64x4(_mm512_castsi256_si512(lo), hi, 1), a));
}

/// ScalarCandidatePass eight candidates at a time. Distances: two descriptors per 512-bit vector,
/// one population count per 64-bit word, the words' counts summed by two rounds of shuffles. Row
/// bookkeeping per lane (lane l sees candidates l, l + 8, ...: its best, the position of its
/// first best, its second best), merged at the end: the best is the smallest lane best, taken at
/// the earliest position among the lanes that hold it; the second best is the second smallest
/// of all lanes' best and second best (they include the two smallest of all). Column bookkeeping
/// by gather and a masked scatter: the eight columns of a step are distinct.
__attribute__((target(VISUAL_GYRO_AVX512_TARGET))) void candidatesAvx512(
    const BriefDescriptor& a, int i, int* inside, int n, const BriefDescriptor* descriptors, int* col_best,
    int* col_best_d, int* best_out, int* second_out, int* best_k_out) {
  // Whole steps of eight read indices past the list: zeros there name a valid column (masked out).
  std::fill(inside + n, inside + n + 8, 0);
  const __m512i aa = _mm512_broadcast_i64x4(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(a.data())));
  const __m256i none = _mm256_set1_epi32(kNone), row = _mm256_set1_epi32(i);
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  __m256i best = none, second = none, best_m = _mm256_setzero_si256();
  for (int m = 0; m < n; m += 8) {
    const int* k = inside + m;
    // Candidates 0|2, 1|3, 4|6, 5|7 in the halves of c0 .. c3: the shuffles below then leave the
    // eight sums in order.
    const __m512i c0 = wordCounts(descriptors, k[0], k[2], aa), c1 = wordCounts(descriptors, k[1], k[3], aa),
                  c2 = wordCounts(descriptors, k[4], k[6], aa), c3 = wordCounts(descriptors, k[5], k[7], aa);
    // Per 128-bit lane: the sum of each vector's two words, for c0 and c1 (then c2 and c3).
    const __m512i s01 = _mm512_add_epi64(_mm512_unpacklo_epi64(c0, c1), _mm512_unpackhi_epi64(c0, c1));
    const __m512i s23 = _mm512_add_epi64(_mm512_unpacklo_epi64(c2, c3), _mm512_unpackhi_epi64(c2, c3));
    // The two 128-bit lanes of each descriptor added.
    const __m512i sums = _mm512_add_epi64(_mm512_shuffle_i64x2(s01, s23, _MM_SHUFFLE(2, 0, 2, 0)),
                                          _mm512_shuffle_i64x2(s01, s23, _MM_SHUFFLE(3, 1, 3, 1)));
    const int left = n - m;
    const __mmask8 valid = left >= 8 ? __mmask8(0xFF) : __mmask8((1u << left) - 1u);
    const __m256i d = _mm256_mask_mov_epi32(none, valid, _mm512_cvtepi64_epi32(sums));
    second = _mm256_min_epi32(second, _mm256_max_epi32(best, d));
    best_m = _mm256_mask_mov_epi32(best_m, _mm256_cmplt_epi32_mask(d, best),
                                   _mm256_add_epi32(_mm256_set1_epi32(m), lane));
    best = _mm256_min_epi32(best, d);
    const __m256i columns = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(k));
    const __m256i old = _mm256_mmask_i32gather_epi32(none, valid, columns, col_best_d, 4);
    const __mmask8 better = _mm256_mask_cmplt_epi32_mask(valid, d, old);
    if (better) {
      _mm256_mask_i32scatter_epi32(col_best_d, better, columns, d, 4);
      _mm256_mask_i32scatter_epi32(col_best, better, columns, row, 4);
    }
  }
  const int b = minLane(best);
  if (b == kNone) {
    *best_out = kNone;
    *second_out = kNone;
    *best_k_out = kNoMatch;
    return;
  }
  const __mmask8 holders = _mm256_cmpeq_epi32_mask(best, _mm256_set1_epi32(b));
  *best_out = b;
  *best_k_out = inside[minLane(_mm256_mask_mov_epi32(none, holders, best_m))];
  // One lane holding the best leaves it out; any other lane holding it too makes it the second.
  const __mmask8 first_holder = static_cast<__mmask8>(holders & (~holders + 1u));
  *second_out = minLane(_mm256_min_epi32(second, _mm256_mask_mov_epi32(best, first_holder, none)));
}

/// bruteForceKernel with AVX-512 VPOPCNTDQ: each row against eight consecutive columns at a
/// time (four 512-bit loads, two descriptors each), row bookkeeping per lane and merged as in
/// candidatesAvx512, column bookkeeping by a plain masked load and store (the columns are
/// consecutive). Columns past the last whole step of eight take the scalar rule after the merge;
/// they come last in search order, so the first of equal distances still wins.
__attribute__((target(VISUAL_GYRO_AVX512_TARGET))) void bruteForceAvx512(const BriefDescriptor* prev, int n_prev,
                                                                         const BriefDescriptor* cur, int n_cur,
                                                                         const SearchTables& t) {
  for (int j = 0; j < n_cur; ++j) {
    t.col_best[j] = kNoMatch;
    t.col_best_d[j] = kNone;
  }
  const int n_whole = n_cur - n_cur % 8;
  const __m256i none = _mm256_set1_epi32(kNone);
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  // Consecutive loads leave the sums in the order 0 2 1 3 4 6 5 7 (see below); this restores it.
  const __m512i order = _mm512_setr_epi64(0, 2, 1, 3, 4, 6, 5, 7);
  for (int i = 0; i < n_prev; ++i) {
    const __m512i aa =
        _mm512_broadcast_i64x4(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(prev[i].data())));
    const __m256i row = _mm256_set1_epi32(i);
    __m256i best = none, second = none, best_j = _mm256_setzero_si256();
    for (int j = 0; j < n_whole; j += 8) {
      const uint64_t* c = cur[j].data();
      const __m512i c0 = _mm512_popcnt_epi64(_mm512_xor_si512(_mm512_loadu_si512(c), aa));
      const __m512i c1 = _mm512_popcnt_epi64(_mm512_xor_si512(_mm512_loadu_si512(c + 8), aa));
      const __m512i c2 = _mm512_popcnt_epi64(_mm512_xor_si512(_mm512_loadu_si512(c + 16), aa));
      const __m512i c3 = _mm512_popcnt_epi64(_mm512_xor_si512(_mm512_loadu_si512(c + 24), aa));
      // Per 128-bit lane the sum of its two words: s01 holds halves of columns 0 2 | 0 2 | 1 3 | 1 3.
      const __m512i s01 = _mm512_add_epi64(_mm512_unpacklo_epi64(c0, c1), _mm512_unpackhi_epi64(c0, c1));
      const __m512i s23 = _mm512_add_epi64(_mm512_unpacklo_epi64(c2, c3), _mm512_unpackhi_epi64(c2, c3));
      const __m512i sums = _mm512_add_epi64(_mm512_shuffle_i64x2(s01, s23, _MM_SHUFFLE(2, 0, 2, 0)),
                                            _mm512_shuffle_i64x2(s01, s23, _MM_SHUFFLE(3, 1, 3, 1)));
      const __m256i d = _mm512_cvtepi64_epi32(_mm512_permutexvar_epi64(order, sums));
      second = _mm256_min_epi32(second, _mm256_max_epi32(best, d));
      best_j = _mm256_mask_mov_epi32(best_j, _mm256_cmplt_epi32_mask(d, best),
                                     _mm256_add_epi32(_mm256_set1_epi32(j), lane));
      best = _mm256_min_epi32(best, d);
      const __m256i old = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(t.col_best_d + j));
      const __mmask8 better = _mm256_cmplt_epi32_mask(d, old);
      _mm256_mask_storeu_epi32(t.col_best_d + j, better, d);
      _mm256_mask_storeu_epi32(t.col_best + j, better, row);
    }
    int b = minLane(best), s = kNone, b_j = kNoMatch;
    if (b != kNone) {
      const __mmask8 holders = _mm256_cmpeq_epi32_mask(best, _mm256_set1_epi32(b));
      b_j = minLane(_mm256_mask_mov_epi32(none, holders, best_j));
      const __mmask8 first_holder = static_cast<__mmask8>(holders & (~holders + 1u));
      s = minLane(_mm256_min_epi32(second, _mm256_mask_mov_epi32(best, first_holder, none)));
    }
    const uint64_t a0 = prev[i][0], a1 = prev[i][1], a2 = prev[i][2], a3 = prev[i][3];
    for (int j = n_whole; j < n_cur; ++j) {
      const int d = static_cast<int>(_mm_popcnt_u64(a0 ^ cur[j][0]) + _mm_popcnt_u64(a1 ^ cur[j][1]) +
                                     _mm_popcnt_u64(a2 ^ cur[j][2]) + _mm_popcnt_u64(a3 ^ cur[j][3]));
      s = std::min(s, std::max(b, d));
      b_j = d < b ? j : b_j;
      b = std::min(b, d);
      if (d < t.col_best_d[j]) {
        t.col_best_d[j] = d;
        t.col_best[j] = i;
      }
    }
    t.row_best[i] = b_j;
    t.row_best_d[i] = b;
    t.row_second_d[i] = s;
  }
}

struct Avx512CandidatePass {
  __attribute__((always_inline)) void operator()(const BriefDescriptor& a, int i, int* inside, int n,
                                                 const BriefDescriptor* descriptors, int* col_best,
                                                 int* col_best_d, int* best, int* second, int* best_k) const {
    candidatesAvx512(a, i, inside, n, descriptors, col_best, col_best_d, best, second, best_k);
  }
};

// Used only when the CPU reports AVX-512 F, VL and VPOPCNTDQ.
__attribute__((target(VISUAL_GYRO_AVX512_TARGET))) void guidedAvx512(const BriefDescriptor* prev, int n_prev,
                                                                     const cv::Point2f* predicted,
                                                                     const float* radii, const GuidedGrid& grid,
                                                                     const SearchTables& tables) {
  guidedKernelBody(prev, n_prev, predicted, radii, grid, tables, Avx512PositionTest(), Avx512CandidatePass());
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif

}  // namespace

GuidedGrid sortIntoGrid(const std::vector<cv::Point2f>& keypoints,
                        const std::vector<BriefDescriptor>& descriptors, float cell_size,
                        const GridBuffers& b) {
  const int n = static_cast<int>(keypoints.size());
  float max_x = 0.f, max_y = 0.f;
  for (const cv::Point2f& p : keypoints) {
    max_x = std::max(max_x, p.x);
    max_y = std::max(max_y, p.y);
  }
  GuidedGrid grid;
  grid.cell_size = cell_size;
  grid.cols = static_cast<int>(max_x / cell_size) + 1;
  grid.rows = static_cast<int>(max_y / cell_size) + 1;
  grid.n = n;
  const size_t n_cells = static_cast<size_t>(grid.cols) * grid.rows;
  b.start->assign(n_cells + 1, 0);
  auto cellOf = [&](const cv::Point2f& p) {
    const int cx = std::clamp(static_cast<int>(p.x / cell_size), 0, grid.cols - 1);
    const int cy = std::clamp(static_cast<int>(p.y / cell_size), 0, grid.rows - 1);
    return static_cast<size_t>(cy) * grid.cols + cx;
  };
  std::vector<int>& start = *b.start;
  for (const cv::Point2f& p : keypoints) ++start[cellOf(p) + 1];
  for (size_t c = 0; c < n_cells; ++c) start[c + 1] += start[c];
  b.cursor->assign(start.begin(), start.end() - 1);
  b.items->resize(n);
  b.points->resize(n + kGuidedPad);
  b.descriptors->resize(n);
  for (int j = 0; j < n; ++j) {
    const int k = (*b.cursor)[cellOf(keypoints[j])]++;
    (*b.items)[k] = j;
    (*b.points)[k] = keypoints[j];
    (*b.descriptors)[k] = descriptors[j];
  }
  b.inside->resize(n + kGuidedPad);
  grid.start = start.data();
  grid.points = b.points->data();
  grid.descriptors = b.descriptors->data();
  grid.inside = b.inside->data();
  return grid;
}

BruteForceKernel bruteForceKernelFor(cpu::CpuLevel level) {
  switch (level) {
    case cpu::CpuLevel::kPortable:
      return bruteForcePortable;
#if defined(__x86_64__) && defined(__GNUC__)
    case cpu::CpuLevel::kPopcnt:
      return cpu::runs(level) ? bruteForcePopcnt : nullptr;
    case cpu::CpuLevel::kAvx512Vbmi:
      return cpu::runs(level) ? bruteForceAvx512 : nullptr;
#endif
    default:
      return nullptr;
  }
}

GuidedKernel guidedKernelFor(cpu::CpuLevel level) {
  switch (level) {
    case cpu::CpuLevel::kPortable:
      return guidedPortable;
#if defined(__x86_64__) && defined(__GNUC__)
    case cpu::CpuLevel::kPopcnt:
      return cpu::runs(level) ? guidedPopcnt : nullptr;
    case cpu::CpuLevel::kAvx2:
      return cpu::runs(level) ? guidedAvx2 : nullptr;
    case cpu::CpuLevel::kAvx512Vbmi:
      return cpu::runs(level) ? guidedAvx512 : nullptr;
#endif
    default:
      return nullptr;
  }
}

// aarch64 has a vector popcount (cnt) in its baseline, which the compiler uses for
// __builtin_popcountll without any flag: the portable kernels are the fast ones there.
BruteForceKernel selectBruteForceKernel(cpu::CpuLevel at_most) {
  return cpu::selectKernel(bruteForceKernelFor, at_most);
}

GuidedKernel selectGuidedKernel(cpu::CpuLevel at_most) { return cpu::selectKernel(guidedKernelFor, at_most); }

BruteForceKernel selectBruteForceKernel() {
  static const BruteForceKernel kernel = selectBruteForceKernel(cpu::activeLevel());
  return kernel;
}

GuidedKernel selectGuidedKernel() {
  static const GuidedKernel kernel = selectGuidedKernel(cpu::activeLevel());
  return kernel;
}

}  // namespace hamming
}  // namespace visual_gyro
