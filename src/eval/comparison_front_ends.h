// Front ends a user would likely pick instead of the native one, for `evaluate --front-end`:
// OpenCV ORB with brute-force Hamming matching and cross-check, and Shi-Tomasi corners tracked by
// pyramidal Lucas-Kanade. They give matched pixels; evaluate turns them into bearings through the
// sequence's camera model, so every estimation method runs on their matches too.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "visual_gyro/visual_gyro.h"

namespace visual_gyro {
namespace eval {

/// A frame-to-frame front end: image in, matched pixels with the previous image out.
class ComparisonFrontEnd {
 public:
  virtual ~ComparisonFrontEnd() = default;
  /// Processes the next image (CV_8UC1). Returns false for the first image (nothing to match);
  /// otherwise `previous[i]` (last image) and `current[i]` (this image) are match i, in pixels.
  /// `times` receives detect, describe and match [ms] (a stage the front end does not have is 0).
  /// Throws std::invalid_argument for an empty or non-8-bit image.
  virtual bool process(const cv::Mat& gray, std::vector<cv::Point2f>* previous,
                       std::vector<cv::Point2f>* current, FrameTimes* times) = 0;
};

/// Whether `front_end` ("native", or a name makeComparisonFrontEnd accepts) gives sub-pixel match
/// positions, which chooses the estimator's covariance model (RotationEstimator::setRefinedPositions):
/// native when `settings` refine them, KLT (Lucas-Kanade tracks are sub-pixel), not ORB (keypoints
/// on the pixel grids of its pyramid levels).
bool refinesPositions(const std::string& front_end, const VisualGyroSettings& settings);

/// Names accepted by makeComparisonFrontEnd: "orb", "klt".
const std::vector<std::string>& comparisonFrontEndNames();

/// "orb": cv::ORB with 1500 features, BFMatcher (Hamming, cross-check).
/// "klt": cv::goodFeaturesToTrack (1500 corners, quality 0.01, 10 px apart) tracked into the next
/// image by cv::calcOpticalFlowPyrLK (21 x 21 window, 3 pyramid levels), tracks with status 1.
/// Throws std::invalid_argument for another name.
std::unique_ptr<ComparisonFrontEnd> makeComparisonFrontEnd(const std::string& name);

}  // namespace eval
}  // namespace visual_gyro
