// The package's fixed-point Gaussian. This file is compiled with full loop vectorisation whatever
// the build type (see the core library's sources in CMakeLists.txt): the filter is written as plain
// loops over 16-bit lanes, which GCC vectorises at -O3 but only partly at -O2 (the RelWithDebInfo
// default), where it would be several times slower than the cv::GaussianBlur it replaces. Its
// result is the same at every optimisation level.
#include "fixed_point_gaussian.h"

#include <vector>

#include <opencv2/imgproc.hpp>

namespace visual_gyro {
namespace fixed_point_gaussian {
namespace {

constexpr int kHalfTaps = kTaps / 2;
static_assert(kHalfTaps + 1 == 7, "FeatureFrontEnd::Workspace::gaussian_weights holds 7 weights");

/// The same result as cv::GaussianBlur (kTaps x kTaps, BORDER_REFLECT_101) on an
/// 8-bit image, bit for bit, given the weights of OpenCV's fixed-point kernel: OpenCV computes
/// H = sum w p (8 fraction bits) per row, then (sum w H + 2^15) >> 16 per column, in 32-bit
/// lanes. Here everything stays in 16-bit lanes (twice as many per instruction): H fits (at most
/// 255 * 256), and the column sum is taken over H's high and low bytes separately (each sum at
/// most 255 * 256), which recombine exactly: (A + 128 + (B >> 8)) >> 8 with A the high bytes' sum
/// and B the low bytes'. Symmetric taps share a multiply. `buffer` holds
/// cols (rows + 2) + kTaps - 1 values. Inlined into one function per instruction set.
__attribute__((always_inline)) inline void filterRows(const cv::Mat& src, const Weights& w,
                                                          cv::Mat* dst, uint16_t* buffer) {
  constexpr int kHalf = kHalfTaps;
  const int cols = src.cols, rows = src.rows;
  auto reflect = [](int i, int n) { return i < 0 ? -i : (i >= n ? 2 * n - 2 - i : i); };

  uint16_t* const horizontal = buffer;  // every row after the horizontal pass
  uint16_t* const padded = horizontal + static_cast<size_t>(cols) * rows;  // one source row
  for (int y = 0; y < rows; ++y) {
    const uint8_t* in = src.ptr<uint8_t>(y);
    uint16_t* __restrict p = padded;
    for (int k = 0; k < kHalf; ++k) {
      p[k] = in[reflect(k - kHalf, cols)];
      p[cols + kHalf + k] = in[reflect(cols + k, cols)];
    }
    for (int x = 0; x < cols; ++x) p[kHalf + x] = in[x];
    uint16_t* __restrict h = horizontal + static_cast<size_t>(y) * cols;
    for (int x = 0; x < cols; ++x) {
      uint16_t acc = static_cast<uint16_t>(w[0] * p[x + kHalf]);
      for (int k = 1; k <= kHalf; ++k) {
        acc = static_cast<uint16_t>(acc + w[k] * static_cast<uint16_t>(p[x + kHalf - k] + p[x + kHalf + k]));
      }
      h[x] = acc;
    }
  }
  uint16_t* __restrict high = padded;      // the row's sums over the high bytes (A)
  uint16_t* __restrict low = padded + cols;  // and over the low bytes (B)
  for (int y = 0; y < rows; ++y) {
    // One pair of taps at a time over the whole row: few streams per loop, which vectorise.
    {
      const uint16_t* __restrict c = horizontal + static_cast<size_t>(y) * cols;
      const uint16_t weight = w[0];
      for (int x = 0; x < cols; ++x) {
        high[x] = static_cast<uint16_t>(weight * (c[x] >> 8));
        low[x] = static_cast<uint16_t>(weight * (c[x] & 0xFF));
      }
    }
    for (int k = 1; k <= kHalf; ++k) {
      const uint16_t* __restrict a = horizontal + static_cast<size_t>(reflect(y - k, rows)) * cols;
      const uint16_t* __restrict b = horizontal + static_cast<size_t>(reflect(y + k, rows)) * cols;
      const uint16_t weight = w[k];
      for (int x = 0; x < cols; ++x) {
        high[x] = static_cast<uint16_t>(high[x] + weight * static_cast<uint16_t>((a[x] >> 8) + (b[x] >> 8)));
        low[x] = static_cast<uint16_t>(low[x] + weight * static_cast<uint16_t>((a[x] & 0xFF) + (b[x] & 0xFF)));
      }
    }
    uint8_t* __restrict out = dst->ptr<uint8_t>(y);
    for (int x = 0; x < cols; ++x) {
      out[x] = static_cast<uint8_t>(static_cast<uint16_t>(high[x] + 128 + (low[x] >> 8)) >> 8);
    }
  }
}

void filterGeneric(const cv::Mat& src, const Weights& w, cv::Mat* dst, uint16_t* buffer) {
  filterRows(src, w, dst, buffer);
}

#if defined(__x86_64__) && defined(__GNUC__)
// Twice the lanes per instruction; used only when the CPU reports AVX2 (runtime dispatch).
__attribute__((target("avx2"))) void filterAvx2(const cv::Mat& src, const Weights& w,
                                                  cv::Mat* dst, uint16_t* buffer) {
  filterRows(src, w, dst, buffer);
}
#endif

}  // namespace

size_t bufferSize(int cols, int rows) { return static_cast<size_t>(cols) * (rows + 2) + kTaps - 1; }

Filter selectFilter() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2")) return filterAvx2;
#endif
  return filterGeneric;
}

bool readWeights(double sigma, Filter filter, Weights* w) {
  cv::Mat probe = cv::Mat::zeros(1, 3 * kTaps, CV_8UC1);
  probe.at<uint8_t>(0, kTaps) = 255;
  cv::Mat response;
  cv::GaussianBlur(probe, response, cv::Size(kTaps, 1), sigma, sigma, cv::BORDER_REFLECT_101);
  int sum = 0;
  for (int k = 0; k <= kHalfTaps; ++k) {
    (*w)[k] = response.at<uint8_t>(0, kTaps + k);
    sum += k == 0 ? (*w)[k] : 2 * (*w)[k];
  }
  if (sum != 256 || (*w)[0] >= 128) return false;
  cv::Mat test(61, 67, CV_8UC1);
  cv::RNG(0x5eed).fill(test, cv::RNG::UNIFORM, 0, 256);
  cv::Mat expected, ours(test.size(), CV_8UC1);
  cv::GaussianBlur(test, expected, cv::Size(kTaps, kTaps), sigma, sigma,
                   cv::BORDER_REFLECT_101);
  std::vector<uint16_t> buffer(bufferSize(test.cols, test.rows));
  filter(test, *w, &ours, buffer.data());
  return cv::countNonZero(ours != expected) == 0;
}

}  // namespace fixed_point_gaussian
}  // namespace visual_gyro
