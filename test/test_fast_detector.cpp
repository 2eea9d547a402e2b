// The package's FAST detector against cv::FAST: the same corners and scores, bit for bit, for
// every instruction set this machine runs, on noise, smoothed noise, rendered and real frames,
// areas of odd sizes inside larger images, tiny and constant images; and its input checks.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "fast_detector.h"
#include "test_support.h"
#include "visual_gyro/renderer.h"

namespace visual_gyro {
namespace {

namespace fd = fast_detector;

/// The thresholds every image is checked at (the front end's range is 1 .. 254; 0 and 255 are
/// the ends of what cv::FAST accepts without wrapping).
const std::vector<int> kThresholds = {0, 1, 5, 10, 20, 40, 100, 254, 255};

struct NamedDetector {
  std::string name;
  fd::Detector detector;
};

/// Every detector this build and CPU can run. The portable one always, SSE2 on every x86-64 CPU.
std::vector<NamedDetector> availableDetectors() {
  std::vector<NamedDetector> detectors;
  for (const cpu::CpuLevel level : cpu::kAllLevels) {
    if (const fd::Detector detector = fd::detectorFor(level)) detectors.push_back({cpu::levelName(level), detector});
  }
  detectors.push_back({"opencv", fd::openCvDetector()});
  return detectors;
}

/// cv::FAST on image(area), non-max suppressed, as (x, y, score) in image coordinates.
std::vector<cv::Point3i> openCvCorners(const cv::Mat& image, const cv::Rect& area, int threshold) {
  std::vector<cv::KeyPoint> keypoints;
  cv::FAST(image(area), keypoints, threshold, /*nonmaxSuppression=*/true, cv::FastFeatureDetector::TYPE_9_16);
  std::vector<cv::Point3i> corners;
  for (const cv::KeyPoint& kp : keypoints) {
    corners.emplace_back(static_cast<int>(kp.pt.x) + area.x, static_cast<int>(kp.pt.y) + area.y,
                         static_cast<int>(kp.response));
    // cv::FAST's positions and scores are whole numbers.
    EXPECT_EQ(static_cast<float>(corners.back().x - area.x), kp.pt.x);
    EXPECT_EQ(static_cast<float>(corners.back().z), kp.response);
  }
  return corners;
}

std::string describe(const std::vector<cv::Point3i>& ours, const std::vector<cv::Point3i>& theirs) {
  std::string text = std::to_string(ours.size()) + " corners against cv::FAST's " + std::to_string(theirs.size());
  const size_t n = std::min(ours.size(), theirs.size());
  for (size_t i = 0; i < n; ++i) {
    if (ours[i] != theirs[i]) {
      text += "; first difference at #" + std::to_string(i) + ": (" + std::to_string(ours[i].x) + ", " +
              std::to_string(ours[i].y) + ", " + std::to_string(ours[i].z) + ") against (" +
              std::to_string(theirs[i].x) + ", " + std::to_string(theirs[i].y) + ", " +
              std::to_string(theirs[i].z) + ")";
      break;
    }
  }
  return text;
}

/// Every available detector gives cv::FAST's corners on image(area) at `threshold`, in its order.
/// The scratch and output buffers are shared across calls, as the front end shares them.
void expectSameAsOpenCv(const cv::Mat& image, const cv::Rect& area, int threshold, const std::string& what) {
  static std::vector<uint8_t> scratch;
  static std::vector<cv::Point3i> corners;
  const std::vector<cv::Point3i> expected = openCvCorners(image, area, threshold);
  for (const NamedDetector& d : availableDetectors()) {
    corners.clear();
    d.detector(image, area, threshold, &scratch, &corners);
    EXPECT_TRUE(corners == expected) << what << ", area " << area << ", threshold " << threshold << ", "
                                     << d.name << ": " << describe(corners, expected);
  }
}

void expectSameAsOpenCvAtAllThresholds(const cv::Mat& image, const std::string& what) {
  for (const int threshold : kThresholds) {
    expectSameAsOpenCv(image, cv::Rect(0, 0, image.cols, image.rows), threshold, what);
  }
}

cv::Mat uniformNoise(cv::Size size, uint64_t seed) {
  cv::Mat noise(size, CV_8UC1);
  cv::RNG(seed).fill(noise, cv::RNG::UNIFORM, 0, 256);
  return noise;
}

TEST(FastDetector, DetectorsOfEachLevelAndTheSelectedOne) {
  EXPECT_NE(fd::detectorFor(cpu::CpuLevel::kPortable), nullptr);
#if defined(__x86_64__)
  if (cpu::runs(cpu::CpuLevel::kSse2)) EXPECT_NE(fd::detectorFor(cpu::CpuLevel::kSse2), nullptr);
#endif
  // The widest vector detector the CPU runs, else cv::FAST (faster than the portable path).
  const fd::Detector selected = fd::selectDetector();
  const std::vector<NamedDetector> detectors = availableDetectors();
  fd::Detector expected = fd::openCvDetector();
  for (const cpu::CpuLevel level : {cpu::CpuLevel::kSse2, cpu::CpuLevel::kAvx2}) {
    if (const fd::Detector d = fd::detectorFor(level)) expected = d;
  }
  EXPECT_EQ(selected, expected) << "the selected detector is not the widest vector one available";
  // Forced levels: cv::FAST below SSE2, SSE2 up to AVX.
  EXPECT_EQ(fd::selectDetector(cpu::CpuLevel::kPortable), fd::openCvDetector());
  if (cpu::runs(cpu::CpuLevel::kSse2))
    EXPECT_EQ(fd::selectDetector(cpu::CpuLevel::kAvx), fd::detectorFor(cpu::CpuLevel::kSse2));
  std::string names;
  for (const NamedDetector& d : detectors) names += " " + d.name;
  std::printf("FAST detectors compared with cv::FAST on this machine:%s\n", names.c_str());
}

// Uniform noise has corners of every score and both signs everywhere, many of them neighbours,
// so the scores and their suppression are both exercised. Sizes around the block widths (16 and
// 32 pixels plus the 6 untested columns) take every path through the blocks.
TEST(FastDetector, SameAsOpenCvOnNoise) {
  for (const cv::Size size : {cv::Size(640, 480), cv::Size(101, 37), cv::Size(38, 9), cv::Size(37, 9),
                              cv::Size(22, 8), cv::Size(21, 7), cv::Size(7, 7), cv::Size(71, 13)}) {
    expectSameAsOpenCvAtAllThresholds(uniformNoise(size, 17 + size.width), "noise " + std::to_string(size.width));
  }
}

// Smoothed noise: scores spread over the low range and plateaus where neighbours tie (equal
// scores suppress each other).
TEST(FastDetector, SameAsOpenCvOnSmoothedNoise) {
  for (const double sigma : {0.7, 1.5, 3.0}) {
    cv::Mat smooth;
    cv::GaussianBlur(uniformNoise(cv::Size(320, 240), 5), smooth, cv::Size(0, 0), sigma);
    expectSameAsOpenCvAtAllThresholds(smooth, "smoothed noise, sigma " + std::to_string(sigma));
  }
}

// Saturated and extreme values: differences of 255 (the largest score is 254), blocks of 0 and
// 255, and single pixels, where the 8-bit arithmetic would wrap if it were not saturating.
TEST(FastDetector, SameAsOpenCvOnExtremeValues) {
  cv::Mat binary = uniformNoise(cv::Size(200, 60), 3);
  cv::threshold(binary, binary, 127, 255, cv::THRESH_BINARY);
  expectSameAsOpenCvAtAllThresholds(binary, "binary noise");
  cv::Mat blocks(64, 96, CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < blocks.rows; ++y) {
    for (int x = 0; x < blocks.cols; ++x) {
      if (((x / 5) + (y / 7)) % 2 == 0) blocks.at<uint8_t>(y, x) = 255;
    }
  }
  blocks.at<uint8_t>(20, 20) = 128;
  blocks.at<uint8_t>(30, 41) = 0;
  expectSameAsOpenCvAtAllThresholds(blocks, "checkerboard");
  cv::Mat dots(40, 80, CV_8UC1, cv::Scalar(0));
  for (int i = 0; i < 30; ++i) dots.at<uint8_t>(3 + i % 34, 3 + (i * 7) % 74) = static_cast<uint8_t>(255 - i);
  expectSameAsOpenCvAtAllThresholds(dots, "dots");
  expectSameAsOpenCvAtAllThresholds(255 - dots, "holes");
}

// Rendered views: the room, the dim room with blur and JPEG (the low thresholds' case) and the
// drive.
TEST(FastDetector, SameAsOpenCvOnRenderedImages) {
  RenderSettings room = test::handheldRoom(640, 480, 500.0);
  RenderSettings dim = room;
  dim.preset = RenderPreset::kDim;
  dim.blur_px = 3.0;
  dim.jpeg_quality = 75;
  RenderSettings drive;
  drive.preset = RenderPreset::kDrive;
  drive.setCentredCamera(752, 480, 460.0);
  for (const auto& [name, scene] : {std::make_pair("room", room), std::make_pair("dim room", dim),
                                    std::make_pair("drive", drive)}) {
    const cv::Mat image = renderView(scene, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
    ASSERT_EQ(image.type(), CV_8UC1);
    expectSameAsOpenCvAtAllThresholds(image, std::string("rendered ") + name);
  }
}

/// The `index`-th image (sorted by name) of a folder of a shared sequence, or empty with the reason.
cv::Mat sharedFrame(const std::string& sequence, const std::string& folder, size_t index, std::string* why) {
  const std::string root = test::sharedSequence(sequence, why);
  if (root.empty()) return cv::Mat();
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(std::filesystem::path(root) / folder)) {
    if (entry.path().extension() == ".png") files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  if (index >= files.size()) {
    *why = "no image " + std::to_string(index) + " in " + root + "/" + folder;
    return cv::Mat();
  }
  cv::Mat image = cv::imread(files[index].string(), cv::IMREAD_GRAYSCALE);
  if (image.empty()) *why = "cannot read " + files[index].string();
  return image;
}

TEST(FastDetector, SameAsOpenCvOnKittiFrames) {
  for (const size_t index : {0, 25}) {
    std::string why;
    const cv::Mat image = sharedFrame("kitti_turn", "image_l", index, &why);
    if (image.empty()) GTEST_SKIP() << why;
    expectSameAsOpenCvAtAllThresholds(image, "kitti_turn frame " + std::to_string(index));
  }
}

TEST(FastDetector, SameAsOpenCvOnEurocFrames) {
  for (const size_t index : {0, 50}) {
    std::string why;
    const cv::Mat image = sharedFrame("euroc_mh01_shake", "cam0/data", index, &why);
    if (image.empty()) GTEST_SKIP() << why;
    expectSameAsOpenCvAtAllThresholds(image, "euroc_mh01_shake frame " + std::to_string(index));
  }
}

// Areas of a larger image (rows not contiguous): only pixels 3 px inside the area are tested and
// the untested ones count as 0 in the suppression, so a corner next to the area's edge can
// survive that a stronger pixel outside the area would suppress in the whole image. Widths run
// through every case of the blocks (narrower than one, one, several with a moved-back last one);
// the areas touch every edge of the image.
TEST(FastDetector, SameAsOpenCvInAreas) {
  const cv::Mat noise = uniformNoise(cv::Size(173, 91), 23);
  cv::Mat smooth;
  cv::GaussianBlur(noise, smooth, cv::Size(0, 0), 1.0);
  for (const cv::Mat& image : {noise, smooth}) {
    for (int width = 1; width <= 75; ++width) {
      for (const int height : {1, 6, 7, 8, 11}) {
        const int x = (width * 37) % (image.cols - width + 1);
        const int y = (width * 11 + height) % (image.rows - height + 1);
        expectSameAsOpenCv(image, cv::Rect(x, y, width, height), 10, "area of noise");
      }
    }
    cv::RNG rng(7);
    for (int i = 0; i < 200; ++i) {
      const int x = rng.uniform(0, image.cols), y = rng.uniform(0, image.rows);
      const int width = rng.uniform(1, image.cols - x + 1), height = rng.uniform(1, image.rows - y + 1);
      expectSameAsOpenCv(image, cv::Rect(x, y, width, height), rng.uniform(0, 60), "random area");
    }
    for (const int threshold : kThresholds) {
      expectSameAsOpenCv(image, cv::Rect(0, 0, image.cols, image.rows), threshold, "whole image");
      expectSameAsOpenCv(image, cv::Rect(1, 2, image.cols - 3, image.rows - 2), threshold, "inner area");
    }
  }
  // The same area gives the same corners whether it is a view (cv::Mat ROI) or a rectangle.
  const cv::Rect area(13, 9, 120, 50);
  const cv::Mat view = noise(area);
  std::vector<uint8_t> scratch;
  std::vector<cv::Point3i> from_view, from_rect;
  fd::detect(view, cv::Rect(0, 0, view.cols, view.rows), 12, &scratch, &from_view);
  fd::detect(noise, area, 12, &scratch, &from_rect);
  ASSERT_EQ(from_view.size(), from_rect.size());
  for (size_t i = 0; i < from_view.size(); ++i) EXPECT_EQ(from_view[i] + cv::Point3i(area.x, area.y, 0), from_rect[i]);
}

// No pixel of an image smaller than 7 x 7 keeps 3 px from every edge: nothing, and no read
// outside it (the memory checkers' builds see any).
TEST(FastDetector, TinyAndEmptyImagesGiveNothing) {
  for (int width = 0; width <= 8; ++width) {
    for (int height = 0; height <= 8; ++height) {
      const cv::Mat image = width * height > 0 ? uniformNoise(cv::Size(width, height), width * 9 + height)
                                               : cv::Mat(height, width, CV_8UC1);
      for (const NamedDetector& d : availableDetectors()) {
        std::vector<uint8_t> scratch;
        std::vector<cv::Point3i> corners;
        d.detector(image, cv::Rect(0, 0, width, height), 1, &scratch, &corners);
        if (width < 7 || height < 7) EXPECT_TRUE(corners.empty()) << width << " x " << height << ", " << d.name;
      }
      // cv::FAST rejects an empty image outright.
      if (width > 0 && height > 0) expectSameAsOpenCv(image, cv::Rect(0, 0, width, height), 1, "tiny image");
    }
  }
}

TEST(FastDetector, ConstantImagesGiveNothing) {
  for (const int value : {0, 1, 128, 254, 255}) {
    const cv::Mat image(50, 70, CV_8UC1, cv::Scalar(value));
    for (const NamedDetector& d : availableDetectors()) {
      std::vector<uint8_t> scratch;
      std::vector<cv::Point3i> corners;
      d.detector(image, cv::Rect(0, 0, image.cols, image.rows), 0, &scratch, &corners);
      EXPECT_TRUE(corners.empty()) << "value " << value << ", " << d.name;
    }
    expectSameAsOpenCvAtAllThresholds(image, "constant " + std::to_string(value));
  }
}

// Thresholds outside 0 .. 255 are clamped (OpenCV 4.6's own vector code wraps them instead, so
// cv::FAST is not the reference there; see the header).
TEST(FastDetector, ThresholdIsClamped) {
  const cv::Mat image = uniformNoise(cv::Size(90, 40), 31);
  const cv::Rect all(0, 0, image.cols, image.rows);
  for (const NamedDetector& d : availableDetectors()) {
    std::vector<uint8_t> scratch;
    std::vector<cv::Point3i> below, zero, above;
    d.detector(image, all, -7, &scratch, &below);
    d.detector(image, all, 0, &scratch, &zero);
    d.detector(image, all, 300, &scratch, &above);
    EXPECT_FALSE(zero.empty()) << d.name;
    EXPECT_TRUE(below == zero) << d.name;
    EXPECT_TRUE(above.empty()) << d.name;
  }
}

TEST(FastDetector, AppendsAndChecksItsInput) {
  const cv::Mat image = uniformNoise(cv::Size(60, 30), 41);
  const cv::Rect all(0, 0, image.cols, image.rows);
  std::vector<uint8_t> scratch;
  std::vector<cv::Point3i> once, twice;
  fd::detect(image, all, 20, &scratch, &once);
  ASSERT_FALSE(once.empty());
  fd::detect(image, all, 20, &scratch, &twice);
  fd::detect(image, all, 20, &scratch, &twice);
  ASSERT_EQ(twice.size(), 2 * once.size());
  EXPECT_TRUE(std::equal(once.begin(), once.end(), twice.begin() + static_cast<std::ptrdiff_t>(once.size())));

  const cv::Mat colour(30, 60, CV_8UC3, cv::Scalar(0, 0, 0));
  EXPECT_THROW(fd::detect(colour, all, 20, &scratch, &twice), std::invalid_argument);
  for (const cv::Rect outside : {cv::Rect(-1, 0, 10, 10), cv::Rect(0, -1, 10, 10), cv::Rect(51, 0, 10, 10),
                                 cv::Rect(0, 21, 10, 10), cv::Rect(0, 0, -1, 10)}) {
    EXPECT_THROW(fd::detect(image, outside, 20, &scratch, &twice), std::invalid_argument) << outside;
  }
}

}  // namespace
}  // namespace visual_gyro
