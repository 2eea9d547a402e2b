// The sub-pixel alignment's kernels: the vector kernels this build uses give the portable ones'
// integers exactly (gradients, every sum, every correlation), including the extreme
// intensities where 16-bit products and 32-bit sums are closest to overflowing; and alignPatch
// finds a known shift, and refuses an edge, a flat patch and a shift beyond its box.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "patch_alignment.h"

namespace visual_gyro {
namespace {

namespace pa = patch_alignment;

bool sameTemplate(const pa::PatchTemplate& a, const pa::PatchTemplate& b) {
  return std::memcmp(a.grad_x, b.grad_x, sizeof(a.grad_x)) == 0 &&
         std::memcmp(a.grad_y, b.grad_y, sizeof(a.grad_y)) == 0 && a.sum_x == b.sum_x && a.sum_y == b.sum_y &&
         a.sum_xx == b.sum_xx && a.sum_xy == b.sum_xy && a.sum_yy == b.sum_yy && a.sum_value == b.sum_value &&
         a.sum_x_value == b.sum_x_value && a.sum_y_value == b.sum_y_value;
}

// Random bytes, a checkerboard of 0 and 255 (the largest gradients and products) and a flat 255.
std::vector<cv::Mat> kernelTestImages() {
  cv::Mat noise(64, 64, CV_8UC1);
  cv::RNG rng(11);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::Mat checker(64, 64, CV_8UC1);
  for (int y = 0; y < checker.rows; ++y)
    for (int x = 0; x < checker.cols; ++x) checker.at<uint8_t>(y, x) = ((x / 2 + y) % 2) ? 255 : 0;
  return {noise, checker, cv::Mat(64, 64, CV_8UC1, cv::Scalar(255))};
}

// Every template and correlation of `build_template` and `correlate` over the test images, against
// the portable kernels; returns how many were compared (fails the test on the first difference).
int compareWithPortable(pa::TemplateKernel build_template, pa::CorrelationKernel correlate) {
  int compared = 0;
  for (const cv::Mat& image : kernelTestImages()) {
    for (int y = 1; y + pa::kSide + 1 < image.rows; y += 3) {
      for (int x = 1; x + pa::kStride + 1 < image.cols; x += 5) {
        pa::PatchTemplate portable, vector;
        std::memset(&portable, 0x5a, sizeof(portable));  // stale contents must not matter
        std::memset(&vector, 0xa5, sizeof(vector));
        pa::buildTemplatePortable(image.ptr<uint8_t>(y) + x, image.step[0], &portable);
        build_template(image.ptr<uint8_t>(y) + x, image.step[0], &vector);
        EXPECT_TRUE(sameTemplate(portable, vector)) << "template at (" << x << ", " << y << ")";
        if (!sameTemplate(portable, vector)) return compared;
        // Correlate against a few other places of the image, as the alignment's shifts do.
        for (const cv::Point offset : {cv::Point(0, 0), cv::Point(-1, 2), cv::Point(3, -1)}) {
          const int cx = std::min(std::max(x + offset.x, 0), image.cols - pa::kStride);
          const int cy = std::min(std::max(y + offset.y, 0), image.rows - pa::kSide);
          const uint8_t* top_left = image.ptr<uint8_t>(cy) + cx;
          const pa::PatchCorrelation a = pa::correlatePortable(portable, top_left, image.step[0]);
          const pa::PatchCorrelation b = correlate(vector, top_left, image.step[0]);
          EXPECT_EQ(a.x, b.x);
          EXPECT_EQ(a.y, b.y);
          EXPECT_EQ(a.intensity, b.intensity);
          if (a.x != b.x || a.y != b.y || a.intensity != b.intensity) return compared;
          ++compared;
        }
      }
    }
  }
  return compared;
}

TEST(PatchAlignmentKernels, VectorKernelsGiveThePortableIntegersExactly) {
  int levels_compared = 0;
  for (const cpu::CpuLevel level : cpu::kAllLevels) {
    if (level == cpu::CpuLevel::kPortable) continue;
    const pa::TemplateKernel build_template = pa::templateKernelFor(level);
    const pa::CorrelationKernel correlate = pa::correlationKernelFor(level);
    ASSERT_EQ(build_template == nullptr, correlate == nullptr) << "a level has both kernels or neither";
    if (build_template == nullptr) continue;  // none of its own, or not in this build or on this CPU
    const int compared = compareWithPortable(build_template, correlate);
    std::printf("level %s: %d template/correlation pairs compared\n", cpu::levelName(level), compared);
    EXPECT_GT(compared, 500);
    ++levels_compared;
  }
  // x86-64 builds always have SSE2; elsewhere only the portable kernels exist (nothing to compare).
#if defined(__SSE2__)
  if (cpu::runs(cpu::CpuLevel::kSse2)) EXPECT_GE(levels_compared, 1);
#endif
  // The kernels in use are those of the highest level that has them.
  EXPECT_EQ(pa::templateKernel(), pa::selectTemplateKernel(cpu::activeLevel()));
  EXPECT_EQ(pa::correlationKernel(), pa::selectCorrelationKernel(cpu::activeLevel()));
  EXPECT_EQ(pa::selectTemplateKernel(cpu::CpuLevel::kPortable), pa::buildTemplatePortable);
  if (cpu::runs(cpu::CpuLevel::kAvx2))
    EXPECT_EQ(pa::selectCorrelationKernel(cpu::CpuLevel::kAvx512Vbmi), pa::correlationKernelFor(cpu::CpuLevel::kAvx2));
}

// The similarity check's sums: every kernel gives the portable integers at every weight, including
// 0 and kBilinearOne and the extreme intensities.
TEST(PatchAlignmentKernels, MomentsKernelsGiveThePortableIntegersExactly) {
  int compared = 0;
  for (const cpu::CpuLevel level : cpu::kAllLevels) {
    const pa::MomentsKernel moments = pa::momentsKernelFor(level);
    if (level == cpu::CpuLevel::kPortable || moments == nullptr) continue;
    std::printf("level %s: moments kernel compared\n", cpu::levelName(level));
    for (const cv::Mat& image : kernelTestImages()) {
      for (int y = 0; y + pa::kSide + 1 < image.rows; y += 7) {
        for (int x = 0; x + pa::kStride + 1 < image.cols; x += 9) {
          for (const int ax : {0, 1, 37, 64, 127, pa::kBilinearOne}) {
            for (const int ay : {0, 5, 64, 100, pa::kBilinearOne}) {
              const uint8_t* previous = image.ptr<uint8_t>(image.rows - pa::kSide - y - 1) + x;
              const uint8_t* current = image.ptr<uint8_t>(y) + x;
              const pa::PatchMoments a = pa::momentsPortable(previous, image.step[0], current, image.step[0], ax, ay);
              const pa::PatchMoments b = moments(previous, image.step[0], current, image.step[0], ax, ay);
              ASSERT_EQ(a.sum_a, b.sum_a);
              ASSERT_EQ(a.sum_b, b.sum_b);
              ASSERT_EQ(a.sum_aa, b.sum_aa);
              ASSERT_EQ(a.sum_bb, b.sum_bb);
              ASSERT_EQ(a.sum_ab, b.sum_ab);
              ++compared;
            }
          }
        }
      }
    }
  }
  std::printf("%d moment sums compared\n", compared);
  if (cpu::runs(cpu::CpuLevel::kAvx2)) EXPECT_GT(compared, 0);
  EXPECT_EQ(pa::momentsKernel(), pa::selectMomentsKernel(cpu::activeLevel()));
  EXPECT_EQ(pa::selectMomentsKernel(cpu::CpuLevel::kSse2), pa::momentsPortable) << "SSE2 has no moments kernel";
}

// The correlation from the integer sums against one computed in doubles with exact bilinear
// weights: the quantisation (1/128 px, 1/16 grey level) moves it by far less than the tracking
// threshold's resolution; identical patches give 1, inverted ones -1, a flat one -1.
TEST(PatchAlignment, CorrelationFromMomentsMatchesTheExactOne) {
  cv::Mat image(64, 64, CV_8UC1);
  cv::RNG rng(3);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(image, image, cv::Size(5, 5), 1.2);
  const auto exact = [&](const uint8_t* previous, const uint8_t* current, double fx, double fy) {
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
    for (int v = 0; v < pa::kSide; ++v)
      for (int u = 0; u < pa::kSide; ++u) {
        const uint8_t* c = current + v * image.step[0] + u;
        const double a = previous[v * image.step[0] + u];
        const double b = (1 - fx) * (1 - fy) * c[0] + fx * (1 - fy) * c[1] + (1 - fx) * fy * c[image.step[0]] +
                         fx * fy * c[image.step[0] + 1];
        sa += a, sb += b, saa += a * a, sbb += b * b, sab += a * b;
      }
    const double n = pa::kSide * pa::kSide;
    return (sab - sa * sb / n) / std::sqrt((saa - sa * sa / n) * (sbb - sb * sb / n));
  };
  double largest = 0.0;
  int compared = 0;
  for (int y = 0; y + pa::kSide + 1 < image.rows; y += 4) {
    for (int x = 0; x + pa::kStride + 1 < image.cols; x += 4) {
      const uint8_t* previous = image.ptr<uint8_t>(20) + 20;
      const uint8_t* current = image.ptr<uint8_t>(y) + x;
      const double fx = rng.uniform(0.0, 1.0), fy = rng.uniform(0.0, 1.0);
      const int ax = static_cast<int>(std::lround(fx * pa::kBilinearOne));
      const int ay = static_cast<int>(std::lround(fy * pa::kBilinearOne));
      const double quantised =
          pa::zeroMeanCorrelation(pa::momentsKernel()(previous, image.step[0], current, image.step[0], ax, ay));
      largest = std::max(largest, std::abs(quantised - exact(previous, current, fx, fy)));
      ++compared;
    }
  }
  std::printf("%d correlations: largest difference from the exact one %.5f\n", compared, largest);
  EXPECT_GT(compared, 100);
  EXPECT_LT(largest, 0.01);
  const uint8_t* patch = image.ptr<uint8_t>(10) + 10;
  EXPECT_NEAR(pa::zeroMeanCorrelation(pa::momentsKernel()(patch, image.step[0], patch, image.step[0], 0, 0)), 1.0,
              1e-12);
  cv::Mat inverted = 255 - image;
  EXPECT_NEAR(pa::zeroMeanCorrelation(pa::momentsKernel()(patch, image.step[0], inverted.ptr<uint8_t>(10) + 10,
                                                          inverted.step[0], 0, 0)),
              -1.0, 1e-12);
  const cv::Mat flat(32, 32, CV_8UC1, cv::Scalar(77));
  EXPECT_EQ(pa::zeroMeanCorrelation(pa::momentsKernel()(patch, image.step[0], flat.ptr<uint8_t>(2) + 2, flat.step[0],
                                                        40, 90)),
            -1.0);
}

// A smooth random pattern sampled at a sub-pixel shift.
cv::Mat blobPattern(double shift_x, double shift_y) {
  cv::Mat_<float> value(48, 48, 120.f);
  cv::RNG rng(5);
  for (int b = 0; b < 40; ++b) {
    const double bx = rng.uniform(0.0, 48.0), by = rng.uniform(0.0, 48.0), sigma = rng.uniform(1.5, 4.0);
    const double amplitude = rng.uniform(-80.0, 80.0);
    for (int y = 0; y < value.rows; ++y)
      for (int x = 0; x < value.cols; ++x) {
        const double dx = x - shift_x - bx, dy = y - shift_y - by;
        value(y, x) += static_cast<float>(amplitude * std::exp(-(dx * dx + dy * dy) / (2 * sigma * sigma)));
      }
  }
  cv::Mat image;
  value.convertTo(image, CV_8UC1);
  return image;
}

TEST(PatchAlignment, FindsAKnownShiftWithEitherKernel) {
  const cv::Mat previous = blobPattern(0.0, 0.0);
  constexpr int kTop = 18, kLeft = 18;  // template's top-left: its centre at (23, 23)
  for (const cv::Point2d shift : {cv::Point2d(0.37, -0.61), cv::Point2d(-1.4, 1.2), cv::Point2d(1.8, 0.2)}) {
    // The same brightness offset everywhere: removed by the alignment.
    const cv::Mat current = blobPattern(shift.x, shift.y) + cv::Scalar(9);
    pa::PatchTemplate patch;
    pa::templateKernel()(previous.ptr<uint8_t>(kTop) + kLeft, previous.step[0], &patch);
    double dx[2], dy[2];
    const pa::CorrelationKernel kernels[2] = {pa::correlatePortable, pa::correlationKernel()};
    for (int k = 0; k < 2; ++k) {
      ASSERT_TRUE(pa::alignPatch(patch, current.ptr<uint8_t>(kTop) + kLeft, current.step[0], kernels[k], 10,
                                 0.001, &dx[k], &dy[k]));
    }
    std::printf("shift (%.2f, %.2f): found (%.3f, %.3f)\n", shift.x, shift.y, dx[0], dy[0]);
    EXPECT_NEAR(dx[0], shift.x, 0.05);
    EXPECT_NEAR(dy[0], shift.y, 0.05);
    EXPECT_EQ(dx[0], dx[1]);
    EXPECT_EQ(dy[0], dy[1]);
  }
}

TEST(PatchAlignment, RefusesEdgesFlatPatchesAndShiftsBeyondItsBox) {
  double dx = 0.0, dy = 0.0;
  // A vertical edge: the position along it is undetermined.
  cv::Mat edge(48, 48, CV_8UC1, cv::Scalar(40));
  edge.colRange(24, 48).setTo(200);
  pa::PatchTemplate patch;
  pa::templateKernel()(edge.ptr<uint8_t>(18) + 18, edge.step[0], &patch);
  EXPECT_FALSE(pa::alignPatch(patch, edge.ptr<uint8_t>(18) + 18, edge.step[0], pa::correlationKernel(), 10,
                              0.01, &dx, &dy));
  const cv::Mat flat(48, 48, CV_8UC1, cv::Scalar(90));
  pa::templateKernel()(flat.ptr<uint8_t>(18) + 18, flat.step[0], &patch);
  EXPECT_FALSE(pa::alignPatch(patch, flat.ptr<uint8_t>(18) + 18, flat.step[0], pa::correlationKernel(), 10,
                              0.01, &dx, &dy));
  // The content lies 4 px away, beyond the +-kMaxShift box.
  const cv::Mat previous = blobPattern(0.0, 0.0), current = blobPattern(4.0, 0.0);
  pa::templateKernel()(previous.ptr<uint8_t>(18) + 18, previous.step[0], &patch);
  EXPECT_FALSE(pa::alignPatch(patch, current.ptr<uint8_t>(18) + 18, current.step[0], pa::correlationKernel(), 10,
                              0.01, &dx, &dy));
}

}  // namespace
}  // namespace visual_gyro
