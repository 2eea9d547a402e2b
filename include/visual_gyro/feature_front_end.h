// Feature front end: FAST corners spread over the image, BRIEF-256 descriptors, Hamming matching
// between consecutive frames.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace visual_gyro {

/// A 256-bit BRIEF descriptor.
using BriefDescriptor = std::array<uint64_t, 4>;

/// Settings of the front end.
struct FrontEndSettings {
  int fast_threshold = 20;      ///< FAST intensity threshold (grey levels)
  int max_features = 1500;      ///< at most this many corners per frame
  int grid_cols = 8;            ///< bucketing grid: corners are spread over cols x rows cells
  int grid_rows = 6;
  double smoothing_sigma = 2.0;  ///< Gaussian smoothing before BRIEF [px]
  double max_ratio = 0.8;        ///< ratio test: best / second-best distance must be below
  int max_hamming = 64;          ///< matches with a larger Hamming distance are dropped
  bool cross_check = true;       ///< keep only mutual best matches
};

/// "" when usable, else what is wrong.
std::string validateFrontEndSettings(const FrontEndSettings& settings);

/// BRIEF sampling pattern: 256 point pairs in a 31x31 patch centred on the corner (offsets in
/// [-15, 15]). Drawn once from an isotropic Gaussian (sigma = 31 / 5, Calonder et al. 2010 "G II")
/// with a fixed splitmix64/Box-Muller sequence (seed 0x62726965665F5F31), clamped to the patch, so it
/// is identical on every platform. pairs[i] = {x1, y1, x2, y2}; bit i is 1 when I(p1) < I(p2).
const std::vector<std::array<int8_t, 4>>& briefPattern();
/// Half size of the BRIEF patch (15): keypoints closer than this to the border are dropped.
constexpr int kBriefHalfPatch = 15;

/// Features of one frame.
struct FrameFeatures {
  std::vector<cv::Point2f> keypoints;          ///< pixel coordinates
  std::vector<BriefDescriptor> descriptors;    ///< one per keypoint
};

/// One match: index into the previous and current frame's keypoints.
struct FeatureMatch {
  int previous = -1;
  int current = -1;
  int distance = 0;  ///< Hamming distance
};

/// Number of differing bits.
int hammingDistance(const BriefDescriptor& a, const BriefDescriptor& b);

/// FAST + grid bucketing + BRIEF + matching. Stateless apart from its settings; thread-safe.
class FeatureFrontEnd {
 public:
  explicit FeatureFrontEnd(const FrontEndSettings& settings = FrontEndSettings());

  /// FAST corners (non-max suppressed), strongest first within each grid cell, at most
  /// max_features in all, none closer than kBriefHalfPatch + 1 to the border. `gray` is CV_8UC1.
  /// Throws std::invalid_argument for an empty or non-8-bit image.
  std::vector<cv::Point2f> detect(const cv::Mat& gray) const;
  /// BRIEF-256 of each keypoint on the smoothed image; keypoints too near the border are removed
  /// (so keypoints and descriptors stay aligned).
  FrameFeatures describe(const cv::Mat& gray, const std::vector<cv::Point2f>& keypoints) const;
  /// Brute-force Hamming matching previous -> current with ratio test, distance limit and
  /// cross-check.
  std::vector<FeatureMatch> match(const FrameFeatures& previous, const FrameFeatures& current) const;

  const FrontEndSettings& settings() const { return settings_; }
  void setSettings(const FrontEndSettings& settings) { settings_ = settings; }

 private:
  FrontEndSettings settings_;
};

}  // namespace visual_gyro
