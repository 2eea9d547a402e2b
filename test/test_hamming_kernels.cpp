// The matching's Hamming search kernels: every instruction set this machine runs gives the
// portable kernel's tables bit for bit, and the portable kernels give what a plain search of
// every candidate in order gives (ties included), on descriptors drawn to collide often, windows
// of every size (none, all, negative radius) and grids of several cell sizes.
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "hamming_kernels.h"
#include "visual_gyro/random.h"

namespace visual_gyro {
namespace {

namespace hm = hamming;
constexpr int kNone = std::numeric_limits<int>::max();


/// Descriptors that differ from a few common ones in a few bits, so equal distances (ties for
/// best, second and column best) are frequent.
std::vector<BriefDescriptor> collidingDescriptors(int n, SplitMix64* rng) {
  std::vector<BriefDescriptor> bases(4);
  for (BriefDescriptor& b : bases)
    for (uint64_t& word : b) word = rng->next();
  std::vector<BriefDescriptor> out(n);
  for (BriefDescriptor& d : out) {
    d = bases[rng->next() % bases.size()];
    const int flips = static_cast<int>(rng->next() % 12);
    for (int f = 0; f < flips; ++f) {
      const uint64_t bit = rng->next() % 256;
      d[bit / 64] ^= uint64_t{1} << (bit % 64);
    }
  }
  return out;
}

/// The five tables of a search, owned.
struct Tables {
  std::vector<int> row_best, row_best_d, row_second_d, col_best, col_best_d;
  Tables(int rows, int cols)
      : row_best(rows, -7), row_best_d(rows, -7), row_second_d(rows, -7), col_best(cols, -7), col_best_d(cols, -7) {}
  hm::SearchTables view() {
    return {row_best.data(), row_best_d.data(), row_second_d.data(), col_best.data(), col_best_d.data()};
  }
  bool operator==(const Tables& o) const {
    return row_best == o.row_best && row_best_d == o.row_best_d && row_second_d == o.row_second_d &&
           col_best == o.col_best && col_best_d == o.col_best_d;
  }
};

/// Current keypoints sorted into a grid by sortIntoGrid (as the front end sorts them), with the
/// padding points made NaN (never inside a window) so reading them cannot matter.
struct SortedGrid {
  std::vector<int> start, cursor, items, inside;
  std::vector<cv::Point2f> points;
  std::vector<BriefDescriptor> descriptors;
  hm::GuidedGrid grid;

  SortedGrid(const std::vector<cv::Point2f>& keypoints, const std::vector<BriefDescriptor>& desc, float cell) {
    grid = hm::sortIntoGrid(keypoints, desc, cell, {&start, &cursor, &items, &inside, &points, &descriptors});
    std::fill(points.begin() + grid.n, points.end(), cv::Point2f(std::nanf(""), std::nanf("")));
  }
};

/// A plain search: every sorted column in order, compared when inside the window, with
/// bruteForceKernel's branches.
Tables plainGuided(const std::vector<BriefDescriptor>& prev, const std::vector<cv::Point2f>& predicted,
                   const std::vector<float>& radii, const SortedGrid& g) {
  const int n_prev = static_cast<int>(prev.size()), n = g.grid.n;
  Tables t(n_prev, n);
  std::fill(t.col_best.begin(), t.col_best.end(), hm::kNoMatch);
  std::fill(t.col_best_d.begin(), t.col_best_d.end(), kNone);
  for (int i = 0; i < n_prev; ++i) {
    int best = kNone, second = kNone, best_k = hm::kNoMatch;
    for (int k = 0; k < n && radii[i] >= 0.f; ++k) {
      const float dx = g.points[k].x - predicted[i].x, dy = g.points[k].y - predicted[i].y;
      const float d2 = dx * dx;
      const float e2 = dy * dy;
      if (d2 + e2 > radii[i] * radii[i]) continue;
      const int d = hammingDistance(prev[i], g.descriptors[k]);
      if (d < best) {
        second = best;
        best = d;
        best_k = k;
      } else if (d < second) {
        second = d;
      }
      if (d < t.col_best_d[k]) {
        t.col_best_d[k] = d;
        t.col_best[k] = i;
      }
    }
    t.row_best[i] = best_k;
    t.row_best_d[i] = best;
    t.row_second_d[i] = second;
  }
  return t;
}

/// One guided case: n_prev windows over n_cur keypoints in a width x height image.
struct GuidedCase {
  std::vector<BriefDescriptor> prev;
  std::vector<cv::Point2f> predicted;
  std::vector<float> radii;
  std::vector<cv::Point2f> keypoints;
  std::vector<BriefDescriptor> current;
};

GuidedCase makeCase(int n_prev, int n_cur, float width, float height, float max_radius, uint64_t seed) {
  SplitMix64 rng(seed);
  GuidedCase c;
  c.prev = collidingDescriptors(n_prev, &rng);
  c.current = collidingDescriptors(n_cur, &rng);
  for (int j = 0; j < n_cur; ++j) {
    // Some keypoints on whole pixels (as FAST gives) so points on a window's edge occur.
    const float x = static_cast<float>(rng.uniform() * width), y = static_cast<float>(rng.uniform() * height);
    c.keypoints.emplace_back(j % 3 == 0 ? std::round(x) : x, j % 3 == 0 ? std::round(y) : y);
  }
  for (int i = 0; i < n_prev; ++i) {
    // Predictions partly off the image, as near its edges they are.
    const float x = static_cast<float>(rng.uniform() * (width + 80.0) - 40.0);
    const float y = static_cast<float>(rng.uniform() * (height + 80.0) - 40.0);
    c.predicted.emplace_back(i % 4 == 0 ? std::round(x) : x, i % 4 == 0 ? std::round(y) : y);
    const double u = rng.uniform();
    float r = static_cast<float>(u * max_radius);
    if (i % 17 == 0) r = -1.f;                // cannot be predicted
    if (i % 19 == 0) r = 0.f;                 // only a keypoint exactly there
    if (i % 23 == 0) r = 10.f * max_radius;  // the whole image
    c.radii.push_back(r);
  }
  return c;
}

TEST(HammingKernels, PortableGuidedEqualsPlainSearch) {
  for (const float cell : {8.f, 16.f, 40.f}) {
    for (uint64_t seed = 1; seed <= 4; ++seed) {
      const GuidedCase c = makeCase(300, 400, 320.f, 240.f, 60.f, seed);
      SortedGrid g(c.keypoints, c.current, cell);
      Tables got(300, 400);
      hm::guidedKernelFor(cpu::CpuLevel::kPortable)(c.prev.data(), 300, c.predicted.data(), c.radii.data(),
                                                        g.grid, got.view());
      const Tables want = plainGuided(c.prev, c.predicted, c.radii, g);
      EXPECT_TRUE(got == want) << "cell " << cell << " seed " << seed;
      // The case is not trivial: windows with several candidates, ties for the best.
      int with_second = 0, tied = 0;
      for (int i = 0; i < 300; ++i) {
        with_second += want.row_second_d[i] != kNone;
        tied += want.row_best_d[i] != kNone && want.row_best_d[i] == want.row_second_d[i];
      }
      EXPECT_GT(with_second, 150);
      EXPECT_GT(tied, 10);
    }
  }
}

TEST(HammingKernels, EveryGuidedKernelEqualsPortableBitForBit) {
  struct Shape {
    int n_prev, n_cur;
    float width, height, max_radius, cell;
  };
  const Shape shapes[] = {{1500, 1500, 1241.f, 376.f, 90.f, 16.f},  // KITTI-like
                          {200, 700, 640.f, 480.f, 150.f, 16.f},    // wide windows
                          {50, 9, 100.f, 100.f, 40.f, 16.f},        // fewer candidates than a vector
                          {30, 1, 50.f, 50.f, 100.f, 8.f},          // one keypoint
                          {40, 0, 50.f, 50.f, 30.f, 16.f},          // none
                          {0, 30, 50.f, 50.f, 30.f, 16.f}};
  int compared = 0;
  for (const cpu::CpuLevel level : cpu::kAllLevels) {
    const hm::GuidedKernel kernel = hm::guidedKernelFor(level);
    const char* name = cpu::levelName(level);
    if (!kernel) continue;  // none of its own, or not in this build or on this CPU
    std::printf("guided kernel %s compared\n", name);
    for (const Shape& s : shapes) {
      for (uint64_t seed = 11; seed <= 13; ++seed) {
        const GuidedCase c = makeCase(s.n_prev, s.n_cur, s.width, s.height, s.max_radius, seed);
        SortedGrid g(c.keypoints, c.current, s.cell);
        Tables want(s.n_prev, s.n_cur), got(s.n_prev, s.n_cur);
        hm::guidedKernelFor(cpu::CpuLevel::kPortable)(c.prev.data(), s.n_prev, c.predicted.data(),
                                                          c.radii.data(), g.grid, want.view());
        // Stale indices in the working list must not matter.
        std::fill(g.inside.begin(), g.inside.end(), s.n_cur > 0 ? s.n_cur - 1 : 0);
        kernel(c.prev.data(), s.n_prev, c.predicted.data(), c.radii.data(), g.grid, got.view());
        EXPECT_TRUE(got == want) << name << ": " << s.n_prev << " x " << s.n_cur << " seed " << seed;
      }
    }
    ++compared;
  }
  EXPECT_GE(compared, 1) << "the portable kernel always runs";
  if (cpu::runs(cpu::CpuLevel::kAvx2)) EXPECT_GE(compared, 3) << "portable, popcnt and avx2 at least";
}

TEST(HammingKernels, EveryBruteForceKernelEqualsPortableBitForBit) {
  SplitMix64 rng(5);
  const std::vector<BriefDescriptor> prev = collidingDescriptors(700, &rng), cur = collidingDescriptors(650, &rng);
  Tables want(700, 650);
  hm::bruteForceKernelFor(cpu::CpuLevel::kPortable)(prev.data(), 700, cur.data(), 650, want.view());
  // The portable kernel against the definition: the first of equal distances wins.
  for (int i = 0; i < 700; i += 37) {
    int best = kNone, best_j = hm::kNoMatch;
    for (int j = 0; j < 650; ++j) {
      const int d = hammingDistance(prev[i], cur[j]);
      if (d < best) best = d, best_j = j;
    }
    EXPECT_EQ(want.row_best[i], best_j);
    EXPECT_EQ(want.row_best_d[i], best);
  }
  // Brute force has kernels of its own for popcnt and AVX-512 (AVX2 adds nothing to it). The
  // column counts cover no whole step of eight, whole steps only and whole steps plus a rest.
  EXPECT_EQ(hm::bruteForceKernelFor(cpu::CpuLevel::kAvx2), nullptr) << "no brute-force kernel of its own for AVX2";
  int compared = 0;
  for (const cpu::CpuLevel level : cpu::kAllLevels) {
    const hm::BruteForceKernel kernel = hm::bruteForceKernelFor(level);
    const char* name = cpu::levelName(level);
    if (!kernel) continue;  // none of its own, or not in this build or on this CPU
    std::printf("brute-force kernel %s compared\n", name);
    ++compared;
    Tables got(700, 650);
    kernel(prev.data(), 700, cur.data(), 650, got.view());
    EXPECT_TRUE(got == want) << name;
    for (const int n_cur : {1, 7, 16, 23}) {
      Tables small_want(700, n_cur), small_got(700, n_cur);
      hm::bruteForceKernelFor(cpu::CpuLevel::kPortable)(prev.data(), 700, cur.data(), n_cur, small_want.view());
      kernel(prev.data(), 700, cur.data(), n_cur, small_got.view());
      EXPECT_TRUE(small_got == small_want) << name << ": 700 x " << n_cur;
    }
  }
  EXPECT_GE(compared, 1) << "the portable kernel always runs";
}

TEST(HammingKernels, TheSelectedKernelsAreThoseOfTheHighestLevel) {
  EXPECT_EQ(hm::selectGuidedKernel(), hm::selectGuidedKernel(cpu::activeLevel()));
  EXPECT_EQ(hm::selectBruteForceKernel(), hm::selectBruteForceKernel(cpu::activeLevel()));
  // A forced level picks the kernel of the highest level at or below it that has one.
  EXPECT_EQ(hm::selectGuidedKernel(cpu::CpuLevel::kPortable), hm::guidedKernelFor(cpu::CpuLevel::kPortable));
  if (cpu::runs(cpu::CpuLevel::kAvx512Bw)) {
    EXPECT_EQ(hm::selectGuidedKernel(cpu::CpuLevel::kAvx512Bw), hm::guidedKernelFor(cpu::CpuLevel::kAvx2));
    EXPECT_EQ(hm::selectBruteForceKernel(cpu::CpuLevel::kAvx512Bw), hm::bruteForceKernelFor(cpu::CpuLevel::kPopcnt));
  }
  if (cpu::runs(cpu::CpuLevel::kAvx512Vbmi))
    EXPECT_EQ(hm::selectBruteForceKernel(), hm::bruteForceKernelFor(cpu::CpuLevel::kAvx512Vbmi));
}

}  // namespace
}  // namespace visual_gyro
