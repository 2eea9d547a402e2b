// BRIEF's test kernels. The gather kernel reads each test's two pixels wherever they lie; the
// permute kernel instead loads the whole 31 x 31 patch once, two rows to a 512-bit register, and
// picks every test's pixel out of the registers with two-register byte permutes (64 tests per
// instruction), which avoids the gathers' one-load-per-lane cost: 0.04 against 0.21 ms for 1 500
// keypoints in row order on a smoothed KITTI frame.
#include "brief_kernels.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <random>
#include <vector>

#include "cpu_features.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace visual_gyro {
namespace brief_kernels {
namespace {

/// BRIEF bits from the gathered test pixels: bit i = first[i] < second[i] (both 16-byte aligned).
BriefDescriptor compareTests(const uint8_t* first, const uint8_t* second) {
  BriefDescriptor descriptor{};
#if defined(__SSE2__)
  // Baseline x86-64: a byte compare and a move-mask give 16 bits at once. The compare is signed,
  // so both sides are shifted by 128 first (an unsigned order then).
  const __m128i bias = _mm_set1_epi8(static_cast<char>(0x80));
  for (int word = 0; word < 4; ++word) {
    uint64_t bits = 0;
    for (int part = 0; part < 4; ++part) {
      const int i = word * 64 + part * 16;
      const __m128i a = _mm_xor_si128(_mm_load_si128(reinterpret_cast<const __m128i*>(first + i)), bias);
      const __m128i b = _mm_xor_si128(_mm_load_si128(reinterpret_cast<const __m128i*>(second + i)), bias);
      const auto mask = static_cast<uint32_t>(_mm_movemask_epi8(_mm_cmplt_epi8(a, b)));
      bits |= static_cast<uint64_t>(mask) << (part * 16);
    }
    descriptor[word] = bits;
  }
#else
  for (int word = 0; word < 4; ++word) {
    uint64_t bits = 0;
    for (int b = 0; b < 64; ++b) {
      bits |= static_cast<uint64_t>(first[word * 64 + b] < second[word * 64 + b]) << b;
    }
    descriptor[word] = bits;
  }
#endif
  return descriptor;
}

BriefDescriptor testsPortable(const uint8_t* centre, std::ptrdiff_t /*step*/, const TestOffsets& offsets) {
  alignas(16) std::array<uint8_t, 256> first, second;
  for (int i = 0; i < 256; ++i) {
    first[i] = centre[offsets.first[i]];
    second[i] = centre[offsets.second[i]];
  }
  return compareTests(first.data(), second.data());
}

#if defined(__x86_64__) && defined(__GNUC__)
// Eight tests per step: the hardware gathers read the 16 pixels as 32-bit words (the pixel in the
// low byte; the caller guarantees the three bytes after each are readable), a 32-bit compare and a
// move-mask give the 8 bits. On a Xeon about twice as fast as gathering the pixels with scalar
// loads into arrays first (0.15 against 0.29 ms for 1 500 keypoints on a KITTI frame); on CPUs
// whose gathers are slow, slower than that (selectKernel times the two).
__attribute__((target("avx2"))) BriefDescriptor testsAvx2(const uint8_t* centre, std::ptrdiff_t /*step*/,
                                                          const TestOffsets& offsets) {
  BriefDescriptor descriptor{};
  const __m256i low_byte = _mm256_set1_epi32(0xFF);
  const int* base = reinterpret_cast<const int*>(centre);
  for (int word = 0; word < 4; ++word) {
    uint64_t bits = 0;
    for (int part = 0; part < 8; ++part) {
      const int i = word * 64 + part * 8;
      const __m256i at_first = _mm256_load_si256(reinterpret_cast<const __m256i*>(offsets.first.data() + i));
      const __m256i at_second = _mm256_load_si256(reinterpret_cast<const __m256i*>(offsets.second.data() + i));
      const __m256i a = _mm256_and_si256(_mm256_i32gather_epi32(base, at_first, 1), low_byte);
      const __m256i b = _mm256_and_si256(_mm256_i32gather_epi32(base, at_second, 1), low_byte);
      const auto mask = static_cast<uint32_t>(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(b, a))));
      bits |= static_cast<uint64_t>(mask) << (part * 8);
    }
    descriptor[word] = bits;
  }
  return descriptor;
}

constexpr int kPatchSide = 2 * kBriefHalfPatch + 1;  // 31: a patch row fits half a register
constexpr int kRowPairs = (kPatchSide + 1) / 2;      // registers holding the patch
constexpr int kRowQuads = (kRowPairs + 1) / 2;       // tables of two registers (128 bytes)
static_assert(kPatchSide <= 32, "a patch row fits 32 bytes");

/// The pattern as the permute kernel reads it. The patch's rows 2k and 2k + 1 (from its top) sit
/// in register k, the first in bytes 0 .. 30 and the second in bytes 32 .. 62; registers 2q and
/// 2q + 1 are table q, of rows 4q .. 4q + 3, whose byte b is row 4q + b / 32, column b % 32. For
/// each side of the tests (0: first pixel, 1: second) and each descriptor word, `index` holds every
/// test's byte in its table and `in_quad[q]` the tests whose pixel lies in table q.
struct PermuteTables {
  alignas(64) uint8_t index[2][4][64];
  uint64_t in_quad[2][4][kRowQuads];
};

PermuteTables buildPermuteTables() {
  PermuteTables tables{};
  const auto& pattern = briefPattern();
  for (int i = 0; i < 256; ++i) {
    for (int side = 0; side < 2; ++side) {
      const int column = pattern[i][2 * side] + kBriefHalfPatch;
      const int row = pattern[i][2 * side + 1] + kBriefHalfPatch;
      tables.index[side][i / 64][i % 64] = static_cast<uint8_t>((row % 4) * 32 + column);
      tables.in_quad[side][i / 64][row / 4] |= uint64_t{1} << (i % 64);
    }
  }
  return tables;
}

const PermuteTables& permuteTables() {
  static const PermuteTables tables = buildPermuteTables();
  return tables;
}

__attribute__((target("avx512f,avx512bw,avx512vbmi"))) BriefDescriptor testsAvx512Vbmi(
    const uint8_t* centre, std::ptrdiff_t step, const TestOffsets& /*offsets*/) {
  static const PermuteTables& tables = permuteTables();
  // Masked loads read exactly the patch's 31 bytes of each row (the other lanes never touch
  // memory), so this kernel reads nothing outside the patch.
  constexpr __mmask64 kRowBytes = (uint64_t{1} << kPatchSide) - 1;
  const uint8_t* top_left = centre - kBriefHalfPatch * step - kBriefHalfPatch;
  static_assert(2 * kRowQuads == kRowPairs, "the tables take the registers two by two");
  __m512i pairs[kRowPairs];
  for (int k = 0; k < kRowPairs; ++k) {
    const uint8_t* upper = top_left + 2 * k * step;
    pairs[k] = _mm512_maskz_loadu_epi8(kRowBytes, upper);
    if (2 * k + 1 < kPatchSide) pairs[k] = _mm512_mask_loadu_epi8(pairs[k], kRowBytes << 32, upper + step - 32);
  }
  BriefDescriptor descriptor{};
  for (int word = 0; word < 4; ++word) {
    // Each lane belongs to one table, so a lane still holds its index until its table's permute
    // (masked to the table's lanes) overwrites it with its pixel: one chain of permutes per side
    // picks every pixel, starting from the indices themselves.
    __m512i first = _mm512_load_si512(tables.index[0][word]);
    __m512i second = _mm512_load_si512(tables.index[1][word]);
    for (int q = 0; q < kRowQuads; ++q) {
      first = _mm512_mask2_permutex2var_epi8(pairs[2 * q], first, tables.in_quad[0][word][q], pairs[2 * q + 1]);
      second = _mm512_mask2_permutex2var_epi8(pairs[2 * q], second, tables.in_quad[1][word][q], pairs[2 * q + 1]);
    }
    descriptor[word] = _mm512_cmplt_epu8_mask(first, second);
  }
  return descriptor;
}
#endif

}  // namespace

TestOffsets testOffsets(std::ptrdiff_t step) {
  const auto& pattern = briefPattern();
  TestOffsets offsets;
  for (int i = 0; i < 256; ++i) {
    offsets.first[i] = static_cast<int32_t>(pattern[i][1] * step + pattern[i][0]);
    offsets.second[i] = static_cast<int32_t>(pattern[i][3] * step + pattern[i][2]);
  }
  return offsets;
}

TestKernel kernelFor(cpu::CpuLevel level) {
  switch (level) {
    case cpu::CpuLevel::kPortable:
      return testsPortable;
#if defined(__x86_64__) && defined(__GNUC__)
    case cpu::CpuLevel::kAvx2:
      return cpu::runs(level) ? testsAvx2 : nullptr;
    case cpu::CpuLevel::kAvx512Vbmi:
      return cpu::runs(level) ? testsAvx512Vbmi : nullptr;
#endif
    default:
      return nullptr;
  }
}

namespace {
// Where fasterKernel leaves its descriptors, so the compiler keeps the timed calls.
volatile uint64_t timing_sink;
}  // namespace

TestKernel fasterKernel(TestKernel first, TestKernel second) {
  // A noise image the size of a few hundred patches, its corners visited in row order as
  // FeatureFrontEnd::describe visits them; the least time of a few alternating rounds, so a
  // moment of load on the machine does not decide.
  constexpr int kWidth = 512, kHeight = 128, kCorners = 256, kRounds = 3;
  std::vector<uint8_t> image(static_cast<size_t>(kWidth) * kHeight);
  std::minstd_rand noise(7);
  for (uint8_t& pixel : image) pixel = static_cast<uint8_t>(noise() >> 8);
  const TestOffsets offsets = testOffsets(kWidth);
  std::vector<const uint8_t*> corners(kCorners);
  const int margin = kBriefHalfPatch + 1;
  for (int k = 0; k < kCorners; ++k) {
    const int y = margin + k * (kHeight - 2 * margin) / kCorners;
    const int x = margin + static_cast<int>(noise() % (kWidth - 2 * margin));
    corners[k] = image.data() + static_cast<size_t>(y) * kWidth + x;
  }
  const TestKernel candidates[2] = {first, second};
  double least[2] = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
  uint64_t sink = 0;
  for (int round = 0; round < kRounds; ++round) {
    for (int c = 0; c < 2; ++c) {
      const auto start = std::chrono::steady_clock::now();
      for (const uint8_t* centre : corners) sink ^= candidates[c](centre, kWidth, offsets)[round % 4];
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      least[c] = std::min(least[c], seconds);
    }
  }
  timing_sink = sink;
  return least[1] < least[0] ? second : first;
}

TestKernel selectKernel(cpu::CpuLevel at_most) {
  const TestKernel chosen = cpu::selectKernel(kernelFor, at_most);
  // The one exception to choosing by level: whether hardware gathers beat plain loads depends on
  // the CPU, and no feature flag tells: twice as fast on a Xeon, twice as slow on an AMD EPYC of
  // family 23 (0.15 against 0.29 and 1.6 against 0.8 ms for 1 500 corners of a KITTI frame). So
  // when the level's kernel is the gather one, it is timed once against the portable kernel.
  if (chosen != nullptr && chosen == kernelFor(cpu::CpuLevel::kAvx2))
    return fasterKernel(chosen, kernelFor(cpu::CpuLevel::kPortable));
  return chosen;
}

TestKernel selectKernel() {
  static const TestKernel kernel = selectKernel(cpu::activeLevel());
  return kernel;
}

}  // namespace brief_kernels
}  // namespace visual_gyro
