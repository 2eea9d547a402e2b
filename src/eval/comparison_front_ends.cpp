// ORB + brute-force and KLT front ends with the settings their OpenCV tutorials use, timed per stage
// like the native front end.
#include "comparison_front_ends.h"

#include <chrono>
#include <stdexcept>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

namespace visual_gyro {
namespace eval {
namespace {

constexpr int kFeatures = 1500;

double elapsedMs(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

void checkImage(const cv::Mat& gray, const std::string& name) {
  if (gray.empty() || gray.type() != CV_8UC1) {
    throw std::invalid_argument(name + " front end: image must be non-empty, 8-bit single channel");
  }
}

class OrbFrontEnd : public ComparisonFrontEnd {
 public:
  OrbFrontEnd() : orb_(cv::ORB::create(kFeatures)), matcher_(cv::NORM_HAMMING, /*crossCheck=*/true) {}

  bool process(const cv::Mat& gray, std::vector<cv::Point2f>* previous, std::vector<cv::Point2f>* current,
               FrameTimes* times) override {
    checkImage(gray, "orb");
    previous->clear();
    current->clear();
    *times = FrameTimes();
    auto t0 = std::chrono::steady_clock::now();
    std::vector<cv::KeyPoint> keypoints;
    orb_->detect(gray, keypoints);
    times->detect = elapsedMs(t0);
    t0 = std::chrono::steady_clock::now();
    cv::Mat descriptors;
    orb_->compute(gray, keypoints, descriptors);
    times->describe = elapsedMs(t0);
    const bool have_previous = has_previous_;
    if (have_previous && !descriptors.empty() && !previous_descriptors_.empty()) {
      t0 = std::chrono::steady_clock::now();
      std::vector<cv::DMatch> matches;
      matcher_.match(previous_descriptors_, descriptors, matches);
      times->match = elapsedMs(t0);
      for (const cv::DMatch& m : matches) {
        previous->push_back(previous_keypoints_[m.queryIdx].pt);
        current->push_back(keypoints[m.trainIdx].pt);
      }
    }
    previous_keypoints_ = std::move(keypoints);
    previous_descriptors_ = descriptors;
    has_previous_ = true;
    return have_previous;
  }

 private:
  cv::Ptr<cv::ORB> orb_;
  cv::BFMatcher matcher_;
  bool has_previous_ = false;
  std::vector<cv::KeyPoint> previous_keypoints_;
  cv::Mat previous_descriptors_;
};

class KltFrontEnd : public ComparisonFrontEnd {
 public:
  bool process(const cv::Mat& gray, std::vector<cv::Point2f>* previous, std::vector<cv::Point2f>* current,
               FrameTimes* times) override {
    checkImage(gray, "klt");
    previous->clear();
    current->clear();
    *times = FrameTimes();
    const bool have_previous = !previous_image_.empty() && previous_image_.size() == gray.size();
    if (have_previous && !previous_corners_.empty()) {
      // Track the corners found in the previous image into this one.
      auto t0 = std::chrono::steady_clock::now();
      std::vector<cv::Point2f> tracked;
      std::vector<uchar> status;
      std::vector<float> error;
      cv::calcOpticalFlowPyrLK(previous_image_, gray, previous_corners_, tracked, status, error, cv::Size(21, 21), 3);
      times->match = elapsedMs(t0);
      for (size_t i = 0; i < tracked.size(); ++i) {
        const cv::Point2f& q = tracked[i];
        if (!status[i] || !(q.x >= 0 && q.y >= 0 && q.x <= gray.cols - 1 && q.y <= gray.rows - 1)) continue;
        previous->push_back(previous_corners_[i]);
        current->push_back(q);
      }
    }
    // Fresh corners in this image for the next pair.
    auto t0 = std::chrono::steady_clock::now();
    cv::goodFeaturesToTrack(gray, previous_corners_, kFeatures, 0.01, 10.0);
    times->detect = elapsedMs(t0);
    previous_image_ = gray.clone();
    return have_previous;
  }

 private:
  cv::Mat previous_image_;
  std::vector<cv::Point2f> previous_corners_;
};

}  // namespace

bool refinesPositions(const std::string& front_end, const VisualGyroSettings& settings) {
  if (front_end == "native") return settings.front_end.subpixel_refinement;
  return front_end == "klt";
}

const std::vector<std::string>& comparisonFrontEndNames() {
  static const std::vector<std::string> names{"orb", "klt"};
  return names;
}

std::unique_ptr<ComparisonFrontEnd> makeComparisonFrontEnd(const std::string& name) {
  if (name == "orb") return std::make_unique<OrbFrontEnd>();
  if (name == "klt") return std::make_unique<KltFrontEnd>();
  throw std::invalid_argument("unknown comparison front end '" + name + "' (orb, klt)");
}

}  // namespace eval
}  // namespace visual_gyro
