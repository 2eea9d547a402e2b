// BRIEF's test kernels: every kernel this build and CPU run gives the documented bits (bit i =
// I(p1) < I(p2), briefPattern()'s pairs) at every patch position of noise, of extreme and of equal
// intensities, in images whose rows are padded or not; and the selected kernel is the permute
// kernel where the CPU has it, else the faster of the others as timed on this CPU.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "brief_kernels.h"

namespace visual_gyro {
namespace {

namespace bk = brief_kernels;

struct NamedKernel {
  std::string name;
  bk::TestKernel kernel;
};

std::vector<NamedKernel> availableKernels() {
  std::vector<NamedKernel> kernels;
  for (const cpu::CpuLevel level : cpu::kAllLevels) {
    if (const bk::TestKernel kernel = bk::kernelFor(level)) kernels.push_back({cpu::levelName(level), kernel});
  }
  return kernels;
}

/// The documented bits, one test at a time.
BriefDescriptor reference(const cv::Mat& image, int x, int y) {
  BriefDescriptor descriptor{};
  const auto& pattern = briefPattern();
  for (int i = 0; i < 256; ++i) {
    const uint8_t a = image.at<uint8_t>(y + pattern[i][1], x + pattern[i][0]);
    const uint8_t b = image.at<uint8_t>(y + pattern[i][3], x + pattern[i][2]);
    if (a < b) descriptor[i / 64] |= uint64_t{1} << (i % 64);
  }
  return descriptor;
}

/// Noise (every order of two pixels), a checkerboard of 0 and 255 (the unsigned extremes, where a
/// signed compare would go wrong) and a flat image (every test equal: no bit set).
std::vector<cv::Mat> testImages() {
  cv::Mat noise(80, 90, CV_8UC1);
  cv::RNG(5).fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::Mat checker(80, 90, CV_8UC1);
  for (int y = 0; y < checker.rows; ++y)
    for (int x = 0; x < checker.cols; ++x) checker.at<uint8_t>(y, x) = ((x + 3 * y) % 5 < 2) ? 255 : 0;
  return {noise, checker, cv::Mat(80, 90, CV_8UC1, cv::Scalar(128))};
}

TEST(BriefKernels, EveryKernelGivesTheDocumentedBits) {
  const std::vector<NamedKernel> kernels = availableKernels();
  std::string names;
  for (const NamedKernel& k : kernels) names += " " + k.name;
  std::printf("BRIEF kernels compared on this machine:%s\n", names.c_str());
  int compared = 0;
  for (const cv::Mat& whole : testImages()) {
    // The image itself, and a view into it whose rows are padded (a row step larger than its width).
    for (const cv::Mat& image : {whole, whole(cv::Rect(3, 2, 61, 70))}) {
      const bk::TestOffsets offsets = bk::testOffsets(static_cast<std::ptrdiff_t>(image.step[0]));
      for (int y = kBriefHalfPatch; y < image.rows - kBriefHalfPatch; ++y) {
        for (int x = kBriefHalfPatch; x < image.cols - kBriefHalfPatch; ++x) {
          // The kernels may read a few bytes past the patch (the caller's check): only where the
          // image's memory holds them.
          const uint8_t* centre = image.ptr<uint8_t>(y) + x;
          const uint8_t* last = image.ptr<uint8_t>(y + kBriefHalfPatch) + x + kBriefHalfPatch;
          if (last + bk::kBytesPastPatch > whole.dataend - 1) continue;
          const BriefDescriptor expected = reference(image, x, y);
          for (const NamedKernel& k : kernels) {
            const BriefDescriptor got = k.kernel(centre, static_cast<std::ptrdiff_t>(image.step[0]), offsets);
            ASSERT_EQ(got, expected) << k.name << " at (" << x << ", " << y << ") in " << image.size();
            ++compared;
          }
        }
      }
    }
  }
  EXPECT_GT(compared, 3 * 2000);
}

TEST(BriefKernels, FlatPatchesSetNoBit) {
  const cv::Mat flat(40, 40, CV_8UC1, cv::Scalar(255));
  const bk::TestOffsets offsets = bk::testOffsets(static_cast<std::ptrdiff_t>(flat.step[0]));
  for (const NamedKernel& k : availableKernels()) {
    EXPECT_EQ(k.kernel(flat.ptr<uint8_t>(20) + 20, static_cast<std::ptrdiff_t>(flat.step[0]), offsets),
              BriefDescriptor{})
        << k.name;
  }
}

TEST(BriefKernels, ThePermuteKernelOrTheFasterOfTheOthersIsSelected) {
  const bk::TestKernel portable = bk::kernelFor(cpu::CpuLevel::kPortable);
  const bk::TestKernel gather = bk::kernelFor(cpu::CpuLevel::kAvx2);
  const bk::TestKernel permute = bk::kernelFor(cpu::CpuLevel::kAvx512Vbmi);
  ASSERT_NE(portable, nullptr);
  const bk::TestKernel selected = bk::selectKernel();
  if (permute != nullptr) {
    EXPECT_EQ(selected, permute);
  } else if (gather != nullptr) {
    EXPECT_TRUE(selected == gather || selected == portable);
    std::printf("selected on this machine: %s\n", selected == gather ? "avx2 (gathers)" : "portable");
  } else {
    EXPECT_EQ(selected, portable);
  }
  // Forced levels: no kernel of a level above the one forced, the timing only between gathers and
  // the portable kernel.
  EXPECT_EQ(bk::selectKernel(cpu::CpuLevel::kPortable), portable);
  EXPECT_EQ(bk::selectKernel(cpu::CpuLevel::kAvx), portable);
  if (gather != nullptr) {
    const bk::TestKernel at_avx512_bw = bk::selectKernel(cpu::CpuLevel::kAvx512Bw);
    EXPECT_TRUE(at_avx512_bw == gather || at_avx512_bw == portable);
  }
}

/// The portable kernel run twenty times over: the same bits in far more time.
BriefDescriptor slowPortable(const uint8_t* centre, std::ptrdiff_t step, const bk::TestOffsets& offsets) {
  static volatile uint64_t sink;
  BriefDescriptor descriptor{};
  for (int i = 0; i < 20; ++i) {
    descriptor = bk::kernelFor(cpu::CpuLevel::kPortable)(centre, step, offsets);
    sink = sink + descriptor[0];
  }
  return descriptor;
}

TEST(BriefKernels, TheTimingPicksTheFasterKernelInEitherOrder) {
  const bk::TestKernel portable = bk::kernelFor(cpu::CpuLevel::kPortable);
  EXPECT_EQ(bk::fasterKernel(slowPortable, portable), portable);
  EXPECT_EQ(bk::fasterKernel(portable, slowPortable), portable);
}

}  // namespace
}  // namespace visual_gyro
