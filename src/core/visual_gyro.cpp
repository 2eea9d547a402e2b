#include "visual_gyro/visual_gyro.h"

#include <chrono>
#include <cmath>
#include <stdexcept>

namespace visual_gyro {

namespace {

double elapsedMs(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

void checkSettings(const VisualGyroSettings& settings) {
  std::string problem = validateFrontEndSettings(settings.front_end);
  if (!problem.empty()) throw std::invalid_argument("invalid front-end settings: " + problem);
  problem = validateSettings(settings.estimator);
  if (!problem.empty()) throw std::invalid_argument("invalid estimator settings: " + problem);
}

void checkCamera(const CameraModel& camera) {
  const std::string problem = camera.validate();
  if (!problem.empty()) throw std::invalid_argument("invalid camera model: " + problem);
}

}  // namespace

VisualGyro::VisualGyro(const CameraModel& camera, const VisualGyroSettings& settings,
                       const WarningSink& warn)
    : camera_(camera), settings_(settings), front_end_(settings.front_end) {
  checkCamera(camera);
  checkSettings(settings);
  estimator_ = createRotationEstimator(settings.estimator, warn);
}

void VisualGyro::reset() {
  has_previous_ = false;
  previous_features_ = FrameFeatures();
  previous_keypoint_bearings_.clear();
  prior_.reset();
}

void VisualGyro::setCamera(const CameraModel& camera) {
  checkCamera(camera);
  camera_ = camera;
  reset();
}

void VisualGyro::setSettings(const VisualGyroSettings& settings) {
  checkSettings(settings);
  settings_ = settings;
  front_end_.setSettings(settings.front_end);
  estimator_->setSettings(settings.estimator);
}

FrameResult VisualGyro::processFrame(const cv::Mat& gray, double stamp) {
  const auto start = std::chrono::steady_clock::now();
  FrameResult result;
  if (gray.empty()) {
    result.error = "empty image";
    return result;
  }
  if (gray.type() != CV_8UC1) {
    result.error = "image must be 8-bit single channel (CV_8UC1), got type " + std::to_string(gray.type());
    return result;
  }
  if (gray.cols != camera_.width() || gray.rows != camera_.height()) {
    result.error = "image is " + std::to_string(gray.cols) + "x" + std::to_string(gray.rows) +
                   " but the camera model is " + std::to_string(camera_.width()) + "x" +
                   std::to_string(camera_.height());
    return result;
  }
  if (!std::isfinite(stamp)) {
    result.error = "stamp is not finite";
    return result;
  }
  if (has_previous_ && !(stamp > previous_stamp_)) {
    result.error = "stamp " + std::to_string(stamp) + " is not after the previous one (" +
                   std::to_string(previous_stamp_) + ")";
    return result;
  }

  StageTimes times;
  FrameFeatures features;
  try {
    auto t0 = std::chrono::steady_clock::now();
    const std::vector<cv::Point2f> corners = front_end_.detect(gray);
    times.detect = elapsedMs(t0);
    t0 = std::chrono::steady_clock::now();
    features = front_end_.describe(gray, corners);
    times.describe = elapsedMs(t0);
  } catch (const std::exception& e) {
    result.error = std::string("front end failed: ") + e.what();
    return result;
  }
  result.features = static_cast<int>(features.keypoints.size());
  std::vector<Eigen::Vector3d> bearings(features.keypoints.size());
  for (size_t i = 0; i < bearings.size(); ++i)
    bearings[i] = camera_.bearing(features.keypoints[i].x, features.keypoints[i].y);

  if (!has_previous_) {
    result.error = "first frame";
  } else {
    const double dt = stamp - previous_stamp_;
    result.dt = dt;
    auto t0 = std::chrono::steady_clock::now();
    const std::vector<FeatureMatch> matches = front_end_.match(previous_features_, features);
    times.match = elapsedMs(t0);
    for (const FeatureMatch& m : matches) {
      result.previous_pixels.push_back(previous_features_.keypoints[m.previous]);
      result.current_pixels.push_back(features.keypoints[m.current]);
      result.previous_bearings.push_back(previous_keypoint_bearings_[m.previous]);
      result.current_bearings.push_back(bearings[m.current]);
    }
    if (settings_.run_estimator) {
      result.rotation = estimator_->estimate(result.previous_bearings, result.current_bearings,
                                             prior_.priorFor(dt));
      prior_.update(result.rotation, dt);
      result.has_estimate = result.rotation.valid;
      result.error = result.rotation.error;
      if (result.rotation.valid) {
        result.angular_velocity = result.rotation.rotation_vector / dt;
        result.angular_velocity_covariance = result.rotation.covariance / (dt * dt);
      }
    }
  }
  times.estimate = result.rotation.times.estimate;
  times.vote = result.rotation.times.vote;
  times.vote_device = result.rotation.times.vote_device;
  times.refine = result.rotation.times.refine;
  times.total = elapsedMs(start);
  result.rotation.times = times;

  has_previous_ = true;
  previous_stamp_ = stamp;
  previous_features_ = std::move(features);
  previous_keypoint_bearings_ = std::move(bearings);
  return result;
}

}  // namespace visual_gyro
