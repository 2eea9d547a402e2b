// The package's fixed-point Gaussian. This file is compiled with full loop vectorisation whatever
// the build type (see the core library's sources in CMakeLists.txt): the filter is written as plain
// loops over 16-bit lanes, which GCC vectorises at -O3 but only partly at -O2 (the RelWithDebInfo
// default), where it would be several times slower than the cv::GaussianBlur it replaces. Its
// result is the same at every optimisation level.
#include "fixed_point_gaussian.h"

#include "cpu_features.h"

#include <vector>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

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
__attribute__((always_inline)) inline int reflect101(int i, int n) {
  return i < 0 ? -i : (i >= n ? 2 * n - 2 - i : i);
}

/// The horizontal pass of every row into `horizontal` (cols x rows values, H = sum w p with 8
/// fraction bits, at most 255 * 256), each value XORed with `bias` (0, or 0x8000 for the signed
/// column pass). `padded` holds one source row with its reflected border.
__attribute__((always_inline)) inline void horizontalPass(const cv::Mat& src, const Weights& w,
                                                          uint16_t bias, uint16_t* horizontal,
                                                          uint16_t* padded) {
  constexpr int kHalf = kHalfTaps;
  const int cols = src.cols, rows = src.rows;
  for (int y = 0; y < rows; ++y) {
    const uint8_t* in = src.ptr<uint8_t>(y);
    uint16_t* __restrict p = padded;
    for (int k = 0; k < kHalf; ++k) {
      p[k] = in[reflect101(k - kHalf, cols)];
      p[cols + kHalf + k] = in[reflect101(cols + k, cols)];
    }
    for (int x = 0; x < cols; ++x) p[kHalf + x] = in[x];
    uint16_t* __restrict h = horizontal + static_cast<size_t>(y) * cols;
    for (int x = 0; x < cols; ++x) {
      uint16_t acc = static_cast<uint16_t>(w[0] * p[x + kHalf]);
      for (int k = 1; k <= kHalf; ++k) {
        acc = static_cast<uint16_t>(acc + w[k] * static_cast<uint16_t>(p[x + kHalf - k] + p[x + kHalf + k]));
      }
      h[x] = static_cast<uint16_t>(acc ^ bias);
    }
  }
}

/// The kTaps rows of horizontal values that output row y's column pass reads (reflected at the
/// image's top and bottom).
__attribute__((always_inline)) inline void tapRows(const uint16_t* horizontal, int y, int rows, int cols,
                                                   const uint16_t* taps[kTaps]) {
  for (int k = -kHalfTaps; k <= kHalfTaps; ++k) {
    taps[kHalfTaps + k] = horizontal + static_cast<size_t>(reflect101(y + k, rows)) * cols;
  }
}

/// One output pixel of the column pass from unbiased horizontal values, exactly as OpenCV
/// computes it: (sum w H + 2^15) >> 16 in 32 bits.
__attribute__((always_inline)) inline uint8_t columnPixel(const uint16_t* const* taps, const Weights& w,
                                                          uint16_t bias, int x) {
  uint32_t sum = static_cast<uint32_t>(w[0]) * static_cast<uint16_t>(taps[kHalfTaps][x] ^ bias);
  for (int k = 1; k <= kHalfTaps; ++k) {
    sum += static_cast<uint32_t>(w[k]) * (static_cast<uint16_t>(taps[kHalfTaps - k][x] ^ bias) +
                                          static_cast<uint16_t>(taps[kHalfTaps + k][x] ^ bias));
  }
  return static_cast<uint8_t>((sum + (1u << 15)) >> 16);
}

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

  uint16_t* const horizontal = buffer;  // every row after the horizontal pass
  uint16_t* const padded = horizontal + static_cast<size_t>(cols) * rows;  // one source row
  horizontalPass(src, w, 0, horizontal, padded);
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
      const uint16_t* __restrict a = horizontal + static_cast<size_t>(reflect101(y - k, rows)) * cols;
      const uint16_t* __restrict b = horizontal + static_cast<size_t>(reflect101(y + k, rows)) * cols;
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
// The column pass in 32-bit lanes with one multiply-add per pair of symmetric taps
// (_mm256_madd_epi16 multiplies two 16-bit values by their weights and adds them): fewer
// instructions than the byte-split sums of filterRows. madd is signed, so the horizontal values are
// stored offset by -32768 (their top bit flipped); over the taps the offset sums to
// -32768 * 256 = -2^23 and is added back before the rounding shift, so the result is exactly
// OpenCV's (sum w H + 2^15) >> 16. Used only when the CPU has AVX2 (filterFor).
__attribute__((target("avx2"))) void filterAvx2(const cv::Mat& src, const Weights& w,
                                                  cv::Mat* dst, uint16_t* buffer) {
  constexpr uint16_t kBias = 0x8000;
  const int cols = src.cols, rows = src.rows;
  uint16_t* const horizontal = buffer;
  horizontalPass(src, w, kBias, horizontal, horizontal + static_cast<size_t>(cols) * rows);
  __m256i weight_pairs[kHalfTaps + 1];
  weight_pairs[0] = _mm256_set1_epi32(w[0]);  // (w0, 0): the centre tap, paired with itself
  for (int k = 1; k <= kHalfTaps; ++k) weight_pairs[k] = _mm256_set1_epi32((w[k] << 16) | w[k]);
  const __m256i rounding = _mm256_set1_epi32((1 << 23) + (1 << 15));
  const uint16_t* taps[kTaps];
  for (int y = 0; y < rows; ++y) {
    tapRows(horizontal, y, rows, cols, taps);
    uint8_t* out = dst->ptr<uint8_t>(y);
    int x = 0;
    for (; x + 16 <= cols; x += 16) {
      const __m256i c = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(taps[kHalfTaps] + x));
      __m256i lo = _mm256_madd_epi16(_mm256_unpacklo_epi16(c, c), weight_pairs[0]);
      __m256i hi = _mm256_madd_epi16(_mm256_unpackhi_epi16(c, c), weight_pairs[0]);
      for (int k = 1; k <= kHalfTaps; ++k) {
        const __m256i a = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(taps[kHalfTaps - k] + x));
        const __m256i b = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(taps[kHalfTaps + k] + x));
        lo = _mm256_add_epi32(lo, _mm256_madd_epi16(_mm256_unpacklo_epi16(a, b), weight_pairs[k]));
        hi = _mm256_add_epi32(hi, _mm256_madd_epi16(_mm256_unpackhi_epi16(a, b), weight_pairs[k]));
      }
      lo = _mm256_srli_epi32(_mm256_add_epi32(lo, rounding), 16);
      hi = _mm256_srli_epi32(_mm256_add_epi32(hi, rounding), 16);
      // The packs undo the unpacks' interleaving within each 128-bit lane; the permute joins the
      // lanes' 8 bytes each.
      const __m256i words = _mm256_packus_epi32(lo, hi);
      const __m256i bytes = _mm256_permute4x64_epi64(_mm256_packus_epi16(words, words), 0x08);
      _mm_storeu_si128(reinterpret_cast<__m128i*>(out + x), _mm256_castsi256_si128(bytes));
    }
    for (; x < cols; ++x) out[x] = columnPixel(taps, w, kBias, x);
  }
}

// GCC 12's AVX-512 headers make their "undefined" vectors by self-initialisation, which
// -Wmaybe-uninitialized reports wherever such an intrinsic is inlined.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
// filterAvx2's column pass over 32 pixels per step. The unpacks and packs work within 128-bit
// lanes as in filterAvx2; the permute joins the four lanes' 8 bytes each.
__attribute__((target("avx2,avx512f,avx512bw"))) void filterAvx512(const cv::Mat& src, const Weights& w,
                                                                    cv::Mat* dst, uint16_t* buffer) {
  constexpr uint16_t kBias = 0x8000;
  const int cols = src.cols, rows = src.rows;
  uint16_t* const horizontal = buffer;
  horizontalPass(src, w, kBias, horizontal, horizontal + static_cast<size_t>(cols) * rows);
  __m512i weight_pairs[kHalfTaps + 1];
  weight_pairs[0] = _mm512_set1_epi32(w[0]);  // (w0, 0): the centre tap, paired with itself
  for (int k = 1; k <= kHalfTaps; ++k) weight_pairs[k] = _mm512_set1_epi32((w[k] << 16) | w[k]);
  const __m512i rounding = _mm512_set1_epi32((1 << 23) + (1 << 15));
  const __m512i lane_bytes = _mm512_setr_epi64(0, 2, 4, 6, 0, 2, 4, 6);
  const uint16_t* taps[kTaps];
  for (int y = 0; y < rows; ++y) {
    tapRows(horizontal, y, rows, cols, taps);
    uint8_t* out = dst->ptr<uint8_t>(y);
    int x = 0;
    for (; x + 32 <= cols; x += 32) {
      const __m512i c = _mm512_loadu_si512(taps[kHalfTaps] + x);
      __m512i lo = _mm512_madd_epi16(_mm512_unpacklo_epi16(c, c), weight_pairs[0]);
      __m512i hi = _mm512_madd_epi16(_mm512_unpackhi_epi16(c, c), weight_pairs[0]);
      for (int k = 1; k <= kHalfTaps; ++k) {
        const __m512i a = _mm512_loadu_si512(taps[kHalfTaps - k] + x);
        const __m512i b = _mm512_loadu_si512(taps[kHalfTaps + k] + x);
        lo = _mm512_add_epi32(lo, _mm512_madd_epi16(_mm512_unpacklo_epi16(a, b), weight_pairs[k]));
        hi = _mm512_add_epi32(hi, _mm512_madd_epi16(_mm512_unpackhi_epi16(a, b), weight_pairs[k]));
      }
      lo = _mm512_srli_epi32(_mm512_add_epi32(lo, rounding), 16);
      hi = _mm512_srli_epi32(_mm512_add_epi32(hi, rounding), 16);
      const __m512i words = _mm512_packus_epi32(lo, hi);
      const __m512i bytes = _mm512_permutexvar_epi64(lane_bytes, _mm512_packus_epi16(words, words));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + x), _mm512_castsi512_si256(bytes));
    }
    for (; x < cols; ++x) out[x] = columnPixel(taps, w, kBias, x);
  }
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif

}  // namespace

size_t bufferSize(int cols, int rows) { return static_cast<size_t>(cols) * (rows + 2) + kTaps - 1; }

Filter filterFor(cpu::CpuLevel level) {
  switch (level) {
    case cpu::CpuLevel::kPortable:
      return filterGeneric;
#if defined(__x86_64__) && defined(__GNUC__)
    case cpu::CpuLevel::kAvx2:
      return cpu::runs(level) ? filterAvx2 : nullptr;
    case cpu::CpuLevel::kAvx512Bw:
      return cpu::runs(level) ? filterAvx512 : nullptr;
#endif
    default:
      return nullptr;
  }
}

Filter selectFilter(cpu::CpuLevel at_most) { return cpu::selectKernel(filterFor, at_most); }

Filter selectFilter() { return selectFilter(cpu::activeLevel()); }

std::vector<std::pair<std::string, Filter>> availableFilters() {
  std::vector<std::pair<std::string, Filter>> filters;
  for (const cpu::CpuLevel level : cpu::kAllLevels)
    if (const Filter filter = filterFor(level)) filters.emplace_back(cpu::levelName(level), filter);
  return filters;
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
