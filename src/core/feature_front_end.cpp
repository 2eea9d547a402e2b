// FAST corners with grid bucketing, BRIEF-256 descriptors and brute-force Hamming matching.
#include "visual_gyro/feature_front_end.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

namespace visual_gyro {

namespace {

// Corners must keep this distance from the border (the BRIEF patch plus one pixel of margin, so a
// keypoint that moves by rounding still has its whole patch inside the image).
constexpr int kDetectBorder = kBriefHalfPatch + 1;

void checkImage(const cv::Mat& gray, const char* where) {
  if (gray.empty()) {
    throw std::invalid_argument(std::string("FeatureFrontEnd::") + where + ": empty image");
  }
  if (gray.type() != CV_8UC1) {
    throw std::invalid_argument(std::string("FeatureFrontEnd::") + where +
                                ": image must be 8-bit single-channel (CV_8UC1), got type " +
                                std::to_string(gray.type()) + " with " +
                                std::to_string(gray.channels()) + " channel(s)");
  }
}

void checkSettings(const FrontEndSettings& settings) {
  const std::string why = validateFrontEndSettings(settings);
  if (!why.empty()) throw std::invalid_argument("FeatureFrontEnd: " + why);
}

/// splitmix64 (Steele, Lea, Flood 2014): tiny, well mixed and fully specified, so the BRIEF
/// pattern is the same wherever it is built.
struct SplitMix64 {
  uint64_t state;
  uint64_t next() {
    uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  /// Uniform in (0, 1]: the top 53 bits, shifted by one so that log() never sees 0.
  double uniform() { return (static_cast<double>(next() >> 11) + 1.0) * 0x1.0p-53; }
};

std::vector<std::array<int8_t, 4>> buildBriefPattern() {
  // Calonder et al. 2010, "G II": both points drawn i.i.d. from an isotropic Gaussian with
  // sigma^2 = S^2 / 25 for a patch of size S = 31.
  constexpr double kSigma = 31.0 / 5.0;
  constexpr uint64_t kSeed = 0x62726965665F5F31ULL;  // "brief__1"
  constexpr double kTwoPi = 6.283185307179586476925286766559;
  SplitMix64 rng{kSeed};
  // Box-Muller produces normals in pairs; they are consumed in order x1, y1, x2, y2, each pair of
  // uniforms (u1, u2) giving sqrt(-2 ln u1) * cos(2 pi u2) then sqrt(-2 ln u1) * sin(2 pi u2).
  bool have_spare = false;
  double spare = 0.0;
  auto normal = [&]() {
    if (have_spare) {
      have_spare = false;
      return spare;
    }
    const double u1 = rng.uniform();
    const double u2 = rng.uniform();
    const double radius = std::sqrt(-2.0 * std::log(u1));
    spare = radius * std::sin(kTwoPi * u2);
    have_spare = true;
    return radius * std::cos(kTwoPi * u2);
  };
  auto offset = [&]() {
    const double value = std::round(kSigma * normal());
    return static_cast<int8_t>(
        std::clamp(value, double(-kBriefHalfPatch), double(kBriefHalfPatch)));
  };
  std::vector<std::array<int8_t, 4>> pairs;
  pairs.reserve(256);
  while (pairs.size() < 256) {
    std::array<int8_t, 4> pair;
    for (auto& value : pair) value = offset();
    // A test comparing a pixel with itself is always 0 and carries no information.
    if (pair[0] == pair[2] && pair[1] == pair[3]) continue;
    pairs.push_back(pair);
  }
  return pairs;
}

struct Candidate {
  cv::Point2f point;
  float response;
};

/// Strongest first; ties broken by position so the selection does not depend on sort stability.
bool stronger(const Candidate& a, const Candidate& b) {
  if (a.response != b.response) return a.response > b.response;
  if (a.point.y != b.point.y) return a.point.y < b.point.y;
  return a.point.x < b.point.x;
}

constexpr int kNoMatch = -1;

/// Brute-force search of every previous descriptor against every current one in a single pass:
/// for each row the best and second-best distance, for each column the best row (for the
/// cross-check). Always inlined, so it is compiled once per instruction set into the callers below
/// (baseline x86-64 has no popcnt instruction and the software popcount is several times slower).
__attribute__((always_inline)) inline void bruteForceKernel(const BriefDescriptor* prev, int n_prev,
                                                            const BriefDescriptor* cur, int n_cur,
                                                            int* row_best, int* row_best_d,
                                                            int* row_second_d, int* col_best,
                                                            int* col_best_d) {
  for (int j = 0; j < n_cur; ++j) {
    col_best[j] = kNoMatch;
    col_best_d[j] = std::numeric_limits<int>::max();
  }
  for (int i = 0; i < n_prev; ++i) {
    const uint64_t a0 = prev[i][0], a1 = prev[i][1], a2 = prev[i][2], a3 = prev[i][3];
    int best = std::numeric_limits<int>::max(), second = std::numeric_limits<int>::max();
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

using KernelFn = void (*)(const BriefDescriptor*, int, const BriefDescriptor*, int, int*, int*,
                          int*, int*, int*);

void bruteForceGeneric(const BriefDescriptor* prev, int n_prev, const BriefDescriptor* cur,
                       int n_cur, int* row_best, int* row_best_d, int* row_second_d, int* col_best,
                       int* col_best_d) {
  bruteForceKernel(prev, n_prev, cur, n_cur, row_best, row_best_d, row_second_d, col_best,
                   col_best_d);
}

#if defined(__x86_64__) && defined(__GNUC__)
// Same kernel with the popcnt instruction enabled; used only when the CPU reports it (runtime
// dispatch, so the binary still runs on any x86-64 and no -march flag is needed).
__attribute__((target("popcnt"))) void bruteForcePopcnt(const BriefDescriptor* prev, int n_prev,
                                                        const BriefDescriptor* cur, int n_cur,
                                                        int* row_best, int* row_best_d,
                                                        int* row_second_d, int* col_best,
                                                        int* col_best_d) {
  bruteForceKernel(prev, n_prev, cur, n_cur, row_best, row_best_d, row_second_d, col_best,
                   col_best_d);
}
#endif

KernelFn selectKernel() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  if (__builtin_cpu_supports("popcnt")) return bruteForcePopcnt;
#endif
  return bruteForceGeneric;
}

}  // namespace

std::string validateFrontEndSettings(const FrontEndSettings& s) {
  std::ostringstream why;
  if (s.fast_threshold < 1 || s.fast_threshold > 254) {
    why << "fast_threshold must be in [1, 254] grey levels, got " << s.fast_threshold;
  } else if (s.max_features < 1) {
    why << "max_features must be positive, got " << s.max_features;
  } else if (s.grid_cols < 1 || s.grid_rows < 1) {
    why << "grid_cols and grid_rows must be positive, got " << s.grid_cols << " x " << s.grid_rows;
  } else if (!std::isfinite(s.smoothing_sigma) || s.smoothing_sigma < 0.0 ||
             s.smoothing_sigma > 20.0) {
    why << "smoothing_sigma must be in [0, 20] px (0 = no smoothing), got " << s.smoothing_sigma;
  } else if (!std::isfinite(s.max_ratio) || s.max_ratio <= 0.0 || s.max_ratio > 1.0) {
    why << "max_ratio must be in (0, 1], got " << s.max_ratio;
  } else if (s.max_hamming < 0 || s.max_hamming > 256) {
    why << "max_hamming must be in [0, 256] bits, got " << s.max_hamming;
  }
  return why.str();
}

const std::vector<std::array<int8_t, 4>>& briefPattern() {
  // Pair i = {x1, y1, x2, y2} (offsets from the keypoint in px); descriptor bit i is set when the
  // smoothed intensity at p1 is lower than at p2: bit_i = I(x + x1, y + y1) < I(x + x2, y + y2).
  // Bit i lives in word i / 64 at bit position i % 64.
  static const std::vector<std::array<int8_t, 4>> pattern = buildBriefPattern();
  return pattern;
}

int hammingDistance(const BriefDescriptor& a, const BriefDescriptor& b) {
  return __builtin_popcountll(a[0] ^ b[0]) + __builtin_popcountll(a[1] ^ b[1]) +
         __builtin_popcountll(a[2] ^ b[2]) + __builtin_popcountll(a[3] ^ b[3]);
}

FeatureFrontEnd::FeatureFrontEnd(const FrontEndSettings& settings) : settings_(settings) {
  checkSettings(settings_);
}

std::vector<cv::Point2f> FeatureFrontEnd::detect(const cv::Mat& gray) const {
  checkImage(gray, "detect");
  checkSettings(settings_);  // setSettings() does not validate
  const int width = gray.cols, height = gray.rows;
  // No pixel can keep the border distance: nothing to detect (not an error).
  if (width < 2 * kDetectBorder + 1 || height < 2 * kDetectBorder + 1) return {};

  std::vector<cv::KeyPoint> corners;
  cv::FAST(gray, corners, settings_.fast_threshold, /*nonmaxSuppression=*/true,
           cv::FastFeatureDetector::TYPE_9_16);

  const int cols = settings_.grid_cols, rows = settings_.grid_rows;
  std::vector<std::vector<Candidate>> cells(static_cast<size_t>(cols) * rows);
  for (const cv::KeyPoint& kp : corners) {
    const float x = kp.pt.x, y = kp.pt.y;
    if (x < kDetectBorder || y < kDetectBorder || x > width - 1 - kDetectBorder ||
        y > height - 1 - kDetectBorder) {
      continue;
    }
    const int cx = std::min(cols - 1, static_cast<int>(x * cols / width));
    const int cy = std::min(rows - 1, static_cast<int>(y * rows / height));
    cells[static_cast<size_t>(cy) * cols + cx].push_back({kp.pt, kp.response});
  }

  // Bucketing: an equal share per cell first, so texture-rich regions cannot take the whole
  // budget; the unused share of sparse cells then goes to the strongest corners left anywhere.
  const size_t budget = static_cast<size_t>(settings_.max_features);
  const size_t per_cell = budget / cells.size();
  std::vector<Candidate> selected, leftovers;
  selected.reserve(budget);
  for (auto& cell : cells) {
    std::sort(cell.begin(), cell.end(), stronger);
    const size_t keep = std::min(per_cell, cell.size());
    selected.insert(selected.end(), cell.begin(), cell.begin() + keep);
    leftovers.insert(leftovers.end(), cell.begin() + keep, cell.end());
  }
  if (selected.size() < budget && !leftovers.empty()) {
    const size_t fill = std::min(budget - selected.size(), leftovers.size());
    std::partial_sort(leftovers.begin(), leftovers.begin() + fill, leftovers.end(), stronger);
    selected.insert(selected.end(), leftovers.begin(), leftovers.begin() + fill);
  }
  std::sort(selected.begin(), selected.end(), stronger);

  std::vector<cv::Point2f> keypoints;
  keypoints.reserve(selected.size());
  for (const Candidate& c : selected) keypoints.push_back(c.point);
  return keypoints;
}

FrameFeatures FeatureFrontEnd::describe(const cv::Mat& gray,
                                        const std::vector<cv::Point2f>& keypoints) const {
  checkImage(gray, "describe");
  checkSettings(settings_);
  FrameFeatures features;
  const int width = gray.cols, height = gray.rows;
  if (keypoints.empty() || width < 2 * kBriefHalfPatch + 1 || height < 2 * kBriefHalfPatch + 1) {
    return features;
  }

  cv::Mat smoothed;
  if (settings_.smoothing_sigma > 0.0) {
    // Kernel covering +-3 sigma, odd.
    const int ksize = 2 * static_cast<int>(std::ceil(3.0 * settings_.smoothing_sigma)) + 1;
    cv::GaussianBlur(gray, smoothed, cv::Size(ksize, ksize), settings_.smoothing_sigma,
                     settings_.smoothing_sigma, cv::BORDER_REFLECT_101);
  } else {
    smoothed = gray;
  }

  // Pattern offsets as byte offsets in the smoothed image, computed once per call.
  const auto& pattern = briefPattern();
  const std::ptrdiff_t step = static_cast<std::ptrdiff_t>(smoothed.step[0]);
  std::array<std::ptrdiff_t, 256> off1, off2;
  for (int i = 0; i < 256; ++i) {
    off1[i] = pattern[i][1] * step + pattern[i][0];
    off2[i] = pattern[i][3] * step + pattern[i][2];
  }

  features.keypoints.reserve(keypoints.size());
  features.descriptors.reserve(keypoints.size());
  for (const cv::Point2f& kp : keypoints) {
    if (!std::isfinite(kp.x) || !std::isfinite(kp.y)) continue;
    const long x = std::lround(kp.x), y = std::lround(kp.y);
    if (x < kBriefHalfPatch || y < kBriefHalfPatch || x > width - 1 - kBriefHalfPatch ||
        y > height - 1 - kBriefHalfPatch) {
      continue;
    }
    const uint8_t* centre = smoothed.ptr<uint8_t>(static_cast<int>(y)) + x;
    BriefDescriptor descriptor{};
    for (int word = 0; word < 4; ++word) {
      uint64_t bits = 0;
      for (int b = 0; b < 64; ++b) {
        const int i = word * 64 + b;
        bits |= static_cast<uint64_t>(centre[off1[i]] < centre[off2[i]]) << b;
      }
      descriptor[word] = bits;
    }
    features.keypoints.push_back(kp);
    features.descriptors.push_back(descriptor);
  }
  return features;
}

std::vector<FeatureMatch> FeatureFrontEnd::match(const FrameFeatures& previous,
                                                 const FrameFeatures& current) const {
  checkSettings(settings_);
  if (previous.keypoints.size() != previous.descriptors.size() ||
      current.keypoints.size() != current.descriptors.size()) {
    throw std::invalid_argument(
        "FeatureFrontEnd::match: keypoints and descriptors differ in count (use describe())");
  }
  std::vector<FeatureMatch> matches;
  const int n_prev = static_cast<int>(previous.descriptors.size());
  const int n_cur = static_cast<int>(current.descriptors.size());
  if (n_prev == 0 || n_cur == 0) return matches;

  static const KernelFn kernel = selectKernel();
  std::vector<int> row_best(n_prev), row_best_d(n_prev), row_second_d(n_prev);
  std::vector<int> col_best(n_cur), col_best_d(n_cur);
  kernel(previous.descriptors.data(), n_prev, current.descriptors.data(), n_cur, row_best.data(),
         row_best_d.data(), row_second_d.data(), col_best.data(), col_best_d.data());

  matches.reserve(std::min(n_prev, n_cur));
  for (int i = 0; i < n_prev; ++i) {
    const int j = row_best[i];
    const int best = row_best_d[i];
    if (j == kNoMatch || best > settings_.max_hamming) continue;
    // Ratio test; with a single candidate there is no second best and nothing to be ambiguous with.
    const int second = row_second_d[i];
    if (second != std::numeric_limits<int>::max() && !(best < settings_.max_ratio * second)) {
      continue;
    }
    if (settings_.cross_check && col_best[j] != i) continue;
    matches.push_back({i, j, best});
  }
  return matches;
}

}  // namespace visual_gyro
