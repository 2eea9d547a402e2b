// The package's FAST-9/16 detector. cv::FAST tests every pixel's circle with a counting loop and
// then scores each corner on its own; here one pass over a row of 16 or 32 pixels computes every
// pixel's score directly in 8-bit lanes (a corner is then a pixel whose score reaches the
// threshold), and non-max suppression runs on whole rows of scores. This file is compiled with
// full optimisation whatever the build type (see the core library's sources in CMakeLists.txt):
// the kernels rely on complete unrolling of their small fixed loops to keep the circle in
// registers. The result is the same at every optimisation level.
#include "fast_detector.h"

#include "cpu_features.h"

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <stdexcept>
#include <string>

#include <opencv2/features2d.hpp>

// The 16- and 32-byte vector helpers below take and return vectors by value. GCC notes that a
// 32-byte vector argument has another ABI without AVX; here they are always inlined into the one
// function compiled for AVX2, so no call ever crosses that ABI and the note does not apply.
#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

namespace visual_gyro {
namespace fast_detector {
namespace {

#define VG_FAST_INLINE __attribute__((always_inline)) inline

constexpr int kRadius = 3;   // circle radius: no pixel closer than this to the area's edge is tested
constexpr int kCircle = 16;  // circle pixels
constexpr int kArc = 9;      // contiguous pixels that make a corner

// The circle as (dx, dy) in contiguous order, clockwise from the top. Only the cyclic order
// matters (a rotation or reversal gives the same arcs); the compass points are 0, 4, 8 and 12.
constexpr int kCircleDx[kCircle] = {0, 1, 2, 3, 3, 3, 2, 1, 0, -1, -2, -3, -3, -3, -2, -1};
constexpr int kCircleDy[kCircle] = {-3, -3, -2, -1, 0, 1, 2, 3, 3, 3, 2, 1, 0, -1, -2, -3};

/// The circle in an image of row step `step` [bytes]. Its pixels are addressed as row offsets
/// plus constant column offsets (k is a constant once the loops are unrolled), which x86 folds
/// into each load's address, rather than read from a table of offsets.
struct Circle {
  std::ptrdiff_t step;
  /// Address of circle pixel k of the centre at `p`.
  const uint8_t* at(const uint8_t* p, int k) const { return p + kCircleDy[k] * step + kCircleDx[k]; }
};

// Scores. For a centre v and its circle pixels, let A be the greatest, over the 16 arcs of 9
// contiguous circle pixels, of the arc's smallest pixel, and B the smallest of the arcs' greatest
// pixels. Some arc is all brighter than v + t exactly when A > v + t, and some arc all darker than
// v - t exactly when B < v - t. So with S = max(A - v, v - B, 0), a pixel is a corner at a
// threshold t >= 0 exactly when S > t, and its cornerScore<16> (the largest t at which it is
// still a corner: the best arc's smallest difference from v, minus 1) is then S - 1. A, B and S
// come from the pixel values alone and fit 8 bits without a sign, so a vector instruction scores
// 16 or 32 pixels at once. For non-max suppression each pixel stores S - 1 when it is a corner and
// 0 otherwise, as cv::FAST does.

/// A (kMaxOfMins) or B (otherwise) of the circle values x(0) .. x(15). The arc from k spans
/// [k, 7] + [8, k + 8] for k < 8 and [k, 15] + [0, k - 8] for k >= 8, so prefix and suffix
/// extremes of the two halves give each arc in one operation: 59 operations for the 16 arcs, for
/// plain ints or vectors of lanes alike. One half's prefixes are kept while the other half's
/// suffixes run, about 11 values at a time; x(k) is read where it is used rather than held.
/// `after_half(best)` runs after each half's 8 arcs (see blockScores).
template <bool kMaxOfMins, class T, class Get, class After>
VG_FAST_INLINE T arcExtreme(const Get& x, const After& after_half) {
  // Always inlined, like `x` in blockScores: a lambda does not take its caller's target (AVX2),
  // so one left out of line (at -O1) would pass its vector results by a different ABI.
  auto inner = [](const T& a, const T& b) __attribute__((always_inline)) -> T {
    if constexpr (kMaxOfMins) {
      return a < b ? a : b;
    } else {
      return a > b ? a : b;
    }
  };
  auto outer = [](const T& a, const T& b) __attribute__((always_inline)) -> T {
    if constexpr (kMaxOfMins) {
      return a > b ? a : b;
    } else {
      return a < b ? a : b;
    }
  };
  constexpr int kHalf = kCircle / 2;
  static_assert(kArc == kHalf + 1, "each arc is a suffix of one half and a prefix of the other");
  T best{};
  for (int half = 0; half < 2; ++half) {
    // Arcs from `first` + k (k = 0 .. 7): suffixes of the half at `first`, prefixes of the other.
    const int first = half * kHalf, other = kHalf - first;
    T prefix[kHalf];
    prefix[0] = x(other);
    for (int j = 1; j < kHalf; ++j) prefix[j] = inner(prefix[j - 1], x(other + j));
    T suffix = x(first + kHalf - 1);
    T arcs = inner(suffix, prefix[kHalf - 1]);
    for (int k = kHalf - 2; k >= 0; --k) {
      suffix = inner(x(first + k), suffix);
      arcs = outer(arcs, inner(suffix, prefix[k]));
    }
    best = half == 0 ? arcs : outer(best, arcs);
    after_half(best);
  }
  return best;
}

// --- One pixel at a time (the portable detector; also the vector detectors' narrow areas) ---

/// The stored score of the pixel at `p`: S - 1 when S > t, else 0.
VG_FAST_INLINE int pixelScore(const uint8_t* p, const Circle& circle, int t) {
  const int v = p[0], high = v + t, low = v - t;
  // Every arc of 9 holds pixel 0 or 8, and pixel 4 or 12 (so two neighbouring compass pixels):
  // most pixels are rejected after two or four reads.
  const int x0 = *circle.at(p, 0), x8 = *circle.at(p, 8);
  bool bright = x0 > high || x8 > high, dark = x0 < low || x8 < low;
  if (!bright && !dark) return 0;
  const int x4 = *circle.at(p, 4), x12 = *circle.at(p, 12);
  bright = bright && (x4 > high || x12 > high);
  dark = dark && (x4 < low || x12 < low);
  if (!bright && !dark) return 0;
  auto x = [&](int k) { return static_cast<int>(*circle.at(p, k)); };
  auto nothing = [](int&) {};
  int s = 0;
  if (bright) s = std::max(s, arcExtreme<true, int>(x, nothing) - v);
  if (dark) s = std::max(s, v - arcExtreme<false, int>(x, nothing));
  return s > t ? s - 1 : 0;
}

/// Stored scores of the row at `row` (the area's row, column 0) into out[3 .. width - 4].
VG_FAST_INLINE void scoreRowScalar(const uint8_t* row, const Circle& circle, int width, int t,
                                   uint8_t* out) {
  for (int x = kRadius; x < width - kRadius; ++x) {
    out[x] = static_cast<uint8_t>(pixelScore(row + x, circle, t));
  }
}

/// Appends the corners of the middle row that beat all 8 neighbours (rows of stored scores).
VG_FAST_INLINE void suppressRowScalar(const uint8_t* up, const uint8_t* mid, const uint8_t* down,
                                      int width, int y, cv::Point offset,
                                      std::vector<cv::Point3i>* corners) {
  for (int x = kRadius; x < width - kRadius; ++x) {
    const int s = mid[x];
    // Neighbours are >= 0, so a kept pixel has s > 0: it is a corner.
    if (s > up[x - 1] && s > up[x] && s > up[x + 1] && s > mid[x - 1] && s > mid[x + 1] &&
        s > down[x - 1] && s > down[x] && s > down[x + 1]) {
      corners->emplace_back(x + offset.x, y + offset.y, s);
    }
  }
}

// --- W pixels at a time, in GCC vector code (SSE2 or AVX2 by the function it is inlined in) ---

template <int W>
struct Lanes {
  typedef uint8_t U8 __attribute__((vector_size(W)));
  typedef uint64_t U64 __attribute__((vector_size(W)));
};

template <int W>
VG_FAST_INLINE typename Lanes<W>::U8 load(const uint8_t* p) {
  typename Lanes<W>::U8 v;
  std::memcpy(&v, p, W);  // an unaligned vector load
  return v;
}

template <int W>
VG_FAST_INLINE void store(uint8_t* p, const typename Lanes<W>::U8& v) {
  std::memcpy(p, &v, W);
}

template <int W>
VG_FAST_INLINE typename Lanes<W>::U8 vmin(const typename Lanes<W>::U8& a, const typename Lanes<W>::U8& b) {
  return a < b ? a : b;
}

template <int W>
VG_FAST_INLINE typename Lanes<W>::U8 vmax(const typename Lanes<W>::U8& a, const typename Lanes<W>::U8& b) {
  return a > b ? a : b;
}

/// max(a - b, 0) lane by lane.
template <int W>
VG_FAST_INLINE typename Lanes<W>::U8 subSat(const typename Lanes<W>::U8& a, const typename Lanes<W>::U8& b) {
  return a - vmin<W>(a, b);
}

/// Whether any lane is non-zero.
template <int W>
VG_FAST_INLINE bool any(const typename Lanes<W>::U8& v) {
  const auto words = reinterpret_cast<typename Lanes<W>::U64>(v);
  uint64_t bits = words[0];
  for (int i = 1; i < W / 8; ++i) bits |= words[i];
  return bits != 0;
}

/// Bit i set when lane i has its top bit set (a movemask): each 64-bit word's eight top bits are
/// gathered into its top byte by one multiplication (the partial products never overlap).
template <int W>
VG_FAST_INLINE uint32_t laneBits(const typename Lanes<W>::U8& v) {
  static_assert(W <= 32, "a 32-bit mask");
  const auto words = reinterpret_cast<typename Lanes<W>::U64>(v);
  uint32_t bits = 0;
  for (int i = 0; i < W / 8; ++i) {
    const uint64_t gathered = (words[i] & 0x8080808080808080ULL) * 0x0002040810204081ULL;
    bits |= static_cast<uint32_t>(gathered >> 56) << (8 * i);
  }
  return bits;
}

/// GCC would interleave the halves of the arc computations, holding about twice as many vectors
/// as there are registers (spilling them). This empty asm, run after each half, makes the reads
/// that follow depend on that half's result (through `centre`), so the halves run one after the
/// other: about 7% faster. GCC on x86-64 only (other compilers check the operand against the
/// instruction set of the template rather than of the AVX2 function it is inlined into).
template <class V>
VG_FAST_INLINE void sequenceAfter(V& best, const uint8_t*& centre) {
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
  asm("" : "+x"(best), "+r"(centre));
#else
  (void)best;
  (void)centre;
#endif
}

/// Stored scores of the W pixels from `p` on (pixelScore lane by lane) into `out`; returns
/// whether any of them is a corner.
template <int W>
VG_FAST_INLINE bool blockScores(const uint8_t* p, const Circle& circle,
                                const typename Lanes<W>::U8& t, uint8_t* out) {
  using U8 = typename Lanes<W>::U8;
  const U8 v = load<W>(p);
  // The compass bounds (see pixelScore): every arc of 9 holds two neighbouring compass pixels,
  // so the best such pair's minimum bounds A from above and its maximum B from below. A block
  // where no lane can reach the threshold is done here. (Deciding per sign would save some arcs
  // but costs a second reduction and branch; it measured slower.)
  U8 q[4];
  for (int i = 0; i < 4; ++i) q[i] = load<W>(circle.at(p, 4 * i));
  U8 a4 = vmin<W>(q[3], q[0]), b4 = vmax<W>(q[3], q[0]);
  for (int i = 0; i < 3; ++i) {
    a4 = vmax<W>(a4, vmin<W>(q[i], q[i + 1]));
    b4 = vmin<W>(b4, vmax<W>(q[i], q[i + 1]));
  }
  if (!any<W>(subSat<W>(vmax<W>(subSat<W>(a4, v), subSat<W>(v, b4)), t))) {
    store<W>(out, U8{});
    return false;
  }
  const uint8_t* centre = p;
  auto x = [&](int k) __attribute__((always_inline)) { return load<W>(circle.at(centre, k)); };
  // A lambda is inlined only when optimising; the asm needs its AVX2 caller's registers.
  auto sequence = [&](U8& best) __attribute__((always_inline)) { sequenceAfter(best, centre); };
  const U8 bright = subSat<W>(arcExtreme<true, U8>(x, sequence), v);
  const U8 s = vmax<W>(bright, subSat<W>(v, arcExtreme<false, U8>(x, sequence)));
  // S - 1 where S > t (then S >= 1), 0 elsewhere.
  const U8 corner = reinterpret_cast<U8>(s > t);
  store<W>(out, (s - 1) & corner);
  return any<W>(corner);
}

/// Stored scores of a row into out[3 .. width - 4] in blocks of W (width - 6 >= W), and for
/// each block whether it holds a corner; the last block is moved back to end at the last
/// column, recomputing a few pixels rather than reading past the area.
template <int W>
VG_FAST_INLINE void scoreRowVector(const uint8_t* row, const Circle& circle, int width, int t,
                                   uint8_t* out, uint8_t* block_has_corner) {
  using U8 = typename Lanes<W>::U8;
  U8 tv;
  for (int i = 0; i < W; ++i) tv[i] = static_cast<uint8_t>(t);
  const int last = width - kRadius - W;
  for (int x = kRadius, block = 0;; x += W, ++block) {
    const int xs = std::min(x, last);
    block_has_corner[block] = blockScores<W>(row + xs, circle, tv, out + xs);
    if (xs == last) break;
  }
}

/// suppressRowScalar in blocks of W (width - 6 >= W), over the blocks of the middle row that
/// hold a corner; a moved-back last block emits only the columns the previous block did not.
template <int W>
VG_FAST_INLINE void suppressRowVector(const uint8_t* up, const uint8_t* mid, const uint8_t* down,
                                      const uint8_t* block_has_corner, int width, int y,
                                      cv::Point offset, std::vector<cv::Point3i>* corners) {
  using U8 = typename Lanes<W>::U8;
  const int last = width - kRadius - W;
  for (int x = kRadius, block = 0;; x += W, ++block) {
    const int xs = std::min(x, last);
    if (block_has_corner[block]) {
      U8 n = vmax<W>(load<W>(up + xs - 1), load<W>(up + xs));
      n = vmax<W>(n, load<W>(up + xs + 1));
      n = vmax<W>(n, load<W>(mid + xs - 1));
      n = vmax<W>(n, load<W>(mid + xs + 1));
      n = vmax<W>(n, load<W>(down + xs - 1));
      n = vmax<W>(n, load<W>(down + xs));
      n = vmax<W>(n, load<W>(down + xs + 1));
      uint32_t keep = laneBits<W>(reinterpret_cast<U8>(load<W>(mid + xs) > n));
      if (xs != x) keep &= ~0u << (x - xs);  // columns the previous block covered
      for (; keep != 0; keep &= keep - 1) {
        const int x_kept = xs + __builtin_ctz(keep);
        corners->emplace_back(x_kept + offset.x, y + offset.y, mid[x_kept]);
      }
    }
    if (xs == last) break;
  }
}

// --- The detector ---

/// Blocks of `lanes` pixels that cover the tested columns of a row `width` pixels wide.
constexpr int blocksPerRow(int width, int lanes) {
  return (width - 2 * kRadius + lanes - 1) / lanes;
}

/// Scratch bytes detectRows<W> needs for any W (the most blocks are those of 16 lanes).
constexpr size_t scratchSize(int width) {
  return 3 * static_cast<size_t>(width) + 3 * static_cast<size_t>(blocksPerRow(width, 16));
}

/// Rows of stored scores in a ring of three (rows y - 2, y - 1, y): row y - 1 is suppressed as
/// soon as row y is scored. The ring starts zeroed, which gives the untested rows 0 .. 2 and
/// columns 0 .. 2 and width - 3 .. width - 1 their score of 0 (stores never touch those columns).
/// W = 0: one pixel at a time. `scratch` holds scratchSize(width) bytes.
template <int W>
VG_FAST_INLINE void detectRows(const uint8_t* base, std::ptrdiff_t step, int width, int height,
                               int t, uint8_t* scratch, cv::Point offset,
                               std::vector<cv::Point3i>* corners) {
  const Circle circle{step};
  std::memset(scratch, 0, 3 * static_cast<size_t>(width));
  auto ringRow = [&](int y) { return scratch + (y % 3) * static_cast<size_t>(width); };
  // Per ring row, whether each block holds a corner (vector detectors).
  const size_t blocks = W > 0 ? static_cast<size_t>(blocksPerRow(width, W)) : 0;
  auto ringFlags = [&](int y) { return scratch + 3 * static_cast<size_t>(width) + (y % 3) * blocks; };
  auto suppress = [&](int y) {
    if constexpr (W > 0) {
      suppressRowVector<W>(ringRow(y - 1), ringRow(y), ringRow(y + 1), ringFlags(y), width, y, offset, corners);
    } else {
      suppressRowScalar(ringRow(y - 1), ringRow(y), ringRow(y + 1), width, y, offset, corners);
    }
  };
  for (int y = kRadius; y < height - kRadius; ++y) {
    const uint8_t* row = base + y * step;
    if constexpr (W > 0) {
      scoreRowVector<W>(row, circle, width, t, ringRow(y), ringFlags(y));
    } else {
      scoreRowScalar(row, circle, width, t, ringRow(y));
    }
    if (y > kRadius) suppress(y - 1);
  }
  // The last tested row's lower neighbour is untested: zero (it holds an older row).
  const int last_row = height - kRadius - 1;
  std::memset(ringRow(last_row + 1), 0, static_cast<size_t>(width));
  suppress(last_row);
}

/// detectRows<0> as a function of its own, which the vector detectors call for areas too narrow
/// for a block (a rare case: it need not be compiled into each of them).
__attribute__((noinline)) void detectRowsScalar(const uint8_t* base, std::ptrdiff_t step, int width,
                                                int height, int t, uint8_t* scratch,
                                                cv::Point offset, std::vector<cv::Point3i>* corners) {
  detectRows<0>(base, step, width, height, t, scratch, offset, corners);
}

void checkInput(const cv::Mat& image, const cv::Rect& area) {
  if (image.type() != CV_8UC1) {
    throw std::invalid_argument("fast_detector: image must be CV_8UC1, got type " +
                                std::to_string(image.type()));
  }
  if (area.x < 0 || area.y < 0 || area.width < 0 || area.height < 0 ||
      area.x + area.width > image.cols || area.y + area.height > image.rows) {
    throw std::invalid_argument("fast_detector: area is not inside the image");
  }
}

/// The whole detection with blocks of at most W pixels (0: one at a time); areas too narrow for
/// a block use the next narrower way.
template <int W>
VG_FAST_INLINE void detectIn(const cv::Mat& image, const cv::Rect& area, int threshold,
                             std::vector<uint8_t>* scratch, std::vector<cv::Point3i>* corners) {
  checkInput(image, area);
  // cv::FAST clamps the threshold to 0..255. At 255 no pixel can be a corner (S <= 255).
  const int t = std::clamp(threshold, 0, 255);
  const int width = area.width, height = area.height;
  if (width < 2 * kRadius + 1 || height < 2 * kRadius + 1 || t == 255) return;
  const size_t needed = scratchSize(width);
  if (scratch->size() < needed) scratch->resize(needed);
  const uint8_t* base = image.ptr<uint8_t>(area.y) + area.x;
  const auto step = static_cast<std::ptrdiff_t>(image.step);
  const int tested = width - 2 * kRadius;
  if constexpr (W >= 32) {
    if (tested >= 32) {
      detectRows<32>(base, step, width, height, t, scratch->data(), area.tl(), corners);
      return;
    }
  }
  if constexpr (W >= 16) {
    if (tested >= 16) {
      detectRows<16>(base, step, width, height, t, scratch->data(), area.tl(), corners);
      return;
    }
  }
  detectRowsScalar(base, step, width, height, t, scratch->data(), area.tl(), corners);
}

void detectPortable(const cv::Mat& image, const cv::Rect& area, int threshold,
                    std::vector<uint8_t>* scratch, std::vector<cv::Point3i>* corners) {
  detectIn<0>(image, area, threshold, scratch, corners);
}

#if defined(__x86_64__) && defined(__GNUC__)
void detectSse2(const cv::Mat& image, const cv::Rect& area, int threshold,
                std::vector<uint8_t>* scratch, std::vector<cv::Point3i>* corners) {
  detectIn<16>(image, area, threshold, scratch, corners);
}

// Twice the lanes per instruction; used only when the CPU reports AVX2 (runtime dispatch).
__attribute__((target("avx2"))) void detectAvx2(const cv::Mat& image, const cv::Rect& area,
                                                int threshold, std::vector<uint8_t>* scratch,
                                                std::vector<cv::Point3i>* corners) {
  detectIn<32>(image, area, threshold, scratch, corners);
}
#endif

/// cv::FAST itself, for CPUs without a vector detector here (OpenCV's own vector code, NEON on
/// AArch64, is several times faster than the portable path). The same checks and output.
void detectWithOpenCv(const cv::Mat& image, const cv::Rect& area, int threshold,
                      std::vector<uint8_t>* /*scratch*/, std::vector<cv::Point3i>* corners) {
  checkInput(image, area);
  // No pixel is 3 px from every edge (cv::FAST also rejects an empty image outright).
  if (area.width < 7 || area.height < 7) return;
  thread_local std::vector<cv::KeyPoint> keypoints;  // reused: no allocation once grown
  cv::FAST(image(area), keypoints, std::clamp(threshold, 0, 255), /*nonmaxSuppression=*/true,
           cv::FastFeatureDetector::TYPE_9_16);
  for (const cv::KeyPoint& kp : keypoints) {
    corners->emplace_back(static_cast<int>(kp.pt.x) + area.x, static_cast<int>(kp.pt.y) + area.y,
                          static_cast<int>(kp.response));
  }
}

#undef VG_FAST_INLINE

}  // namespace

Detector detectorFor(cpu::CpuLevel level) {
  switch (level) {
    case cpu::CpuLevel::kPortable:
      return detectPortable;
#if defined(__x86_64__) && defined(__GNUC__)
    case cpu::CpuLevel::kSse2:
      return cpu::runs(level) ? detectSse2 : nullptr;
    case cpu::CpuLevel::kAvx2:
      return cpu::runs(level) ? detectAvx2 : nullptr;
#endif
    default:
      return nullptr;
  }
}

Detector openCvDetector() { return detectWithOpenCv; }

Detector selectDetector(cpu::CpuLevel at_most) {
  if (const Detector detector = cpu::selectKernel(detectorFor, at_most, cpu::CpuLevel::kSse2)) return detector;
  return detectWithOpenCv;
}

Detector selectDetector() { return selectDetector(cpu::activeLevel()); }

void detect(const cv::Mat& image, const cv::Rect& area, int threshold, std::vector<uint8_t>* scratch,
            std::vector<cv::Point3i>* corners) {
  static const Detector detector = selectDetector();
  detector(image, area, threshold, scratch, corners);
}

}  // namespace fast_detector
}  // namespace visual_gyro
