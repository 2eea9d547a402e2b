#include "visual_gyro/visual_gyro.h"

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <sstream>
#include <stdexcept>

namespace visual_gyro {

namespace {

double elapsedMs(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

void checkSettings(const VisualGyroSettings& settings) {
  const std::string problem = validateVisualGyroSettings(settings);
  if (!problem.empty()) throw std::invalid_argument("invalid settings: " + problem);
}

void checkCamera(const CameraModel& camera) {
  std::string problem = camera.validate();
  if (!problem.empty()) throw std::invalid_argument("invalid camera model: " + problem);
  problem = calibrationProblem(camera);
  if (!problem.empty()) throw std::invalid_argument("implausible calibration: " + problem);
}

/// True when two images have the same size and bytes.
bool bitIdentical(const cv::Mat& a, const cv::Mat& b) {
  if (a.empty() || b.empty() || a.size() != b.size() || a.type() != b.type()) return false;
  const size_t row_bytes = static_cast<size_t>(a.cols) * a.elemSize();
  for (int r = 0; r < a.rows; ++r) {
    if (std::memcmp(a.ptr(r), b.ptr(r), row_bytes) != 0) return false;
  }
  return true;
}

std::string formatNumber(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

// The few settings a user sets, those only method `paper` reads, and those the node reads once at
// start; every other setting is an expert one that changes live. A name that is no setting throws
// when the table is built, so these lists cannot drift from it.
const char* const kUserSettings[] = {"method", "backend", "max_features", "hypotheses"};
const char* const kPaperOnlySettings[] = {"centroid_subtraction", "yaw_bin_deg", "yaw_window_deg"};
const char* const kStartOnlySettings[] = {"backend"};

template <class Apply, size_t N>
void tag(std::vector<SettingField<VisualGyroSettings>>* fields, const char* const (&names)[N], Apply apply) {
  for (const char* name : names) {
    auto it = std::find_if(fields->begin(), fields->end(), [name](const auto& f) { return f.name == name; });
    if (it == fields->end()) throw std::logic_error(std::string("no setting '") + name + "' to tag");
    apply(&*it);
  }
}

}  // namespace

const std::vector<SettingField<VisualGyroSettings>>& visualGyroSettingFields() {
  using S = VisualGyroSettings;
  using Field = SettingField<S>;
  static const std::vector<Field> fields = [] {
    std::vector<Field> all;
    for (const auto& f : frontEndSettingFields()) all.push_back(nestedField(f, &S::front_end));
    for (const auto& f : estimatorSettingFields()) all.push_back(nestedField(f, &S::estimator));
    all.push_back(doubleField<S>("min_dt", &S::min_dt, 0.0, 1.0, "s",
                                 "a time step below this is skipped (the frame is not used)"));
    all.push_back(doubleField<S>("max_rate_dps", &S::max_rate_dps, 1.0, 1e6, "deg/s",
                                 "an estimated angular rate above this is invalid"));
    tag(&all, kUserSettings, [](Field* f) { f->tier = SettingTier::kUser; });
    tag(&all, kPaperOnlySettings, [](Field* f) { f->tier = SettingTier::kPaperOnly; });
    tag(&all, kStartOnlySettings, [](Field* f) { f->live = false; });
    return all;
  }();
  return fields;
}

const SettingField<VisualGyroSettings>* findSetting(const std::string& name) {
  for (const auto& f : visualGyroSettingFields())
    if (f.name == name) return &f;
  return nullptr;
}

std::string applySetting(VisualGyroSettings* settings, const std::string& name, const std::string& value) {
  return applyField(settings, visualGyroSettingFields(), name, value);
}

std::string settingsMarkdownTable() {
  return tieredSettingsMarkdown(settingRows(visualGyroSettingFields(), VisualGyroSettings()));
}

std::string validateVisualGyroSettings(const VisualGyroSettings& settings) {
  // The front end's and the estimator's fields are part of this table: one pass checks them all.
  return checkRanges(settings, visualGyroSettingFields());
}

std::string checkRatePlausible(const Eigen::Vector3d& rotation_vector, double dt,
                               const VisualGyroSettings& settings) {
  if (!(dt > 0.0)) return "time step " + formatNumber(dt) + " s is not positive";
  const double rate_dps = rotation_vector.norm() / dt * kRadToDeg;
  if (!(rate_dps <= settings.max_rate_dps)) {
    return "rate " + formatNumber(rate_dps) + " deg/s above max_rate_dps (" +
           formatNumber(settings.max_rate_dps) + " deg/s) over a " + formatNumber(dt) +
           " s step: implausible";
  }
  return "";
}

const char* pairMatchingName(PairMatching matching) {
  switch (matching) {
    case PairMatching::kGuided: return "guided";
    case PairMatching::kGlobal: return "global";
    case PairMatching::kGlobalFallback: return "global_fallback";
    case PairMatching::kNone: break;
  }
  return "";
}

std::ostream& operator<<(std::ostream& out, PairMatching matching) { return out << pairMatchingName(matching); }

double matchFootprint(const CameraModel& camera) {
  return (2.0 * kBriefHalfPatch + 1.0) / std::min(camera.fx(), camera.fy());
}

VisualGyro::VisualGyro(const CameraModel& camera, const VisualGyroSettings& settings,
                       const WarningSink& warn)
    : camera_(camera), settings_(settings), front_end_(settings.front_end),
      half_front_end_(settings.front_end) {
  checkCamera(camera);
  checkSettings(settings);
  estimator_ = createRotationEstimator(settings.estimator, warn);
  backend_ = estimator_->backend();
  estimator_->setRefinedPositions(settings.front_end.subpixel_refinement);
  estimator_->setMatchFootprint(matchFootprint(camera_));
}

void VisualGyro::reset() {
  has_previous_ = false;
  previous_gray_ = cv::Mat();
  previous_features_ = FrameFeatures();
  previous_keypoint_bearings_.clear();
  half_previous_ready_ = false;
  half_resolution_used_ = false;
  prior_.reset();
  prior_uncertainty_rad_ = 0.0;
  search_parallax_rad_ = 0.0;
}

void VisualGyro::setCamera(const CameraModel& camera) {
  checkCamera(camera);
  camera_ = camera;
  estimator_->setMatchFootprint(matchFootprint(camera_));
  estimator_->forgetCamera();
  calibration_fit_.reset();
  reset();
}

void VisualGyro::setSettings(const VisualGyroSettings& settings) {
  checkSettings(settings);
  settings_ = settings;
  front_end_.setSettings(settings.front_end);
  half_front_end_.setSettings(settings.front_end);
  estimator_->setSettings(settings.estimator);
  estimator_->setRefinedPositions(settings.front_end.subpixel_refinement);
}

FrameResult VisualGyro::processFrame(const cv::Mat& gray, double stamp) {
  const auto start = std::chrono::steady_clock::now();
  FrameResult result;
  // Every early return before the front end leaves the state untouched.
  if (rejectImage(gray, &result) || rejectStamp(stamp, &result) || rejectContent(gray, stamp, &result)) {
    return result;
  }
  half_current_ready_ = false;
  half_matched_ = false;
  half_resolution_used_ = false;
  if (!describeFrame(gray, stamp, &result)) return result;
  if (!has_previous_) {
    result.status = FrameStatus::kFirstFrame;
    result.reason = "first frame: nothing to pair with yet";
  } else if (!estimatePair(gray, stamp, &result)) {
    return result;
  }
  result.times.total = elapsedMs(start);
  keepAsPrevious(gray, stamp);
  return result;
}

bool VisualGyro::rejectImage(const cv::Mat& gray, FrameResult* result) const {
  auto reject = [result](const std::string& why) {
    result->status = FrameStatus::kImageRejected;
    result->reason = why;
    return true;
  };
  if (gray.empty()) return reject("empty image");
  if (gray.type() != CV_8UC1) {
    return reject("image must be 8-bit single channel (CV_8UC1), got type " + std::to_string(gray.type()));
  }
  if (gray.cols != camera_.width() || gray.rows != camera_.height()) {
    return reject("image is " + std::to_string(gray.cols) + "x" + std::to_string(gray.rows) +
                  " but the camera model is " + std::to_string(camera_.width()) + "x" +
                  std::to_string(camera_.height()));
  }
  if (gray.cols < kMinImageSide || gray.rows < kMinImageSide) {
    return reject("image " + std::to_string(gray.cols) + "x" + std::to_string(gray.rows) +
                  " is smaller than the descriptor patch (at least " + std::to_string(kMinImageSide) + "x" +
                  std::to_string(kMinImageSide) + " px)");
  }
  return false;
}

bool VisualGyro::rejectStamp(double stamp, FrameResult* result) const {
  if (!std::isfinite(stamp)) {
    result->status = FrameStatus::kStampRejected;
    result->reason = "stamp is not finite";
    return true;
  }
  if (has_previous_ && !(stamp > previous_stamp_)) {
    result->status = FrameStatus::kStampRejected;
    result->reason = "stamp " + std::to_string(stamp) + " is not after the previous one (" +
                     std::to_string(previous_stamp_) + ")";
    return true;
  }
  if (has_previous_ && stamp - previous_stamp_ < settings_.min_dt) {
    result->dt = stamp - previous_stamp_;
    result->status = FrameStatus::kTimeStepTooSmall;
    result->reason = "time step " + formatNumber(result->dt) + " s below min_dt (" +
                     formatNumber(settings_.min_dt) + " s): frame skipped";
    return true;
  }
  return false;
}

bool VisualGyro::rejectContent(const cv::Mat& gray, double stamp, FrameResult* result) const {
  // Checked before the frozen camera: a uniform image (lens cap, darkness, overexposure) is
  // identical to the next one too, though the camera is not what fails.
  cv::Scalar grey_mean, grey_stddev;
  cv::meanStdDev(gray, grey_mean, grey_stddev);
  if (grey_stddev[0] < kMinTextureStdDev) {
    if (has_previous_) result->dt = stamp - previous_stamp_;
    std::ostringstream why;
    why.precision(3);
    why << "image has no texture (grey levels " << grey_mean[0] << " +- " << grey_stddev[0]
        << "): lens cap, darkness or overexposure?";
    result->status = FrameStatus::kNoTexture;
    result->reason = why.str();
    return true;
  }
  if (has_previous_ && bitIdentical(gray, previous_gray_)) {
    // A driver repeating its last frame with a new stamp would otherwise read as "no rotation"
    // while the camera may be turning. The previous image keeps its stamp: it is when that
    // content was captured.
    result->dt = stamp - previous_stamp_;
    result->status = FrameStatus::kFrozenImage;
    result->reason = "image identical to the previous one (camera frozen?)";
    return true;
  }
  return false;
}

bool VisualGyro::describeFrame(const cv::Mat& gray, double stamp, FrameResult* result) {
  FrameTimes& times = result->times;
  FrameFeatures& features = features_;
  try {
    auto t0 = std::chrono::steady_clock::now();
    front_end_.detect(gray, &corners_);
    times.detect = elapsedMs(t0);
    t0 = std::chrono::steady_clock::now();
    front_end_.describe(gray, corners_, &features);
    times.describe = elapsedMs(t0);
  } catch (const std::exception& e) {
    result->status = FrameStatus::kFrontEndFailed;
    result->reason = std::string("front end failed: ") + e.what();
    return false;
  }
  result->features = static_cast<int>(features.keypoints.size());
  if (features.keypoints.empty()) {
    // Like a uniform image: nothing to pair with, so the previous image stays.
    if (has_previous_) result->dt = stamp - previous_stamp_;
    result->status = FrameStatus::kNoTexture;
    result->reason = "image has no texture: no corner found";
    return false;
  }
  std::vector<Eigen::Vector3d>& bearings = bearings_;
  bearings.resize(features.keypoints.size());
  for (size_t i = 0; i < bearings.size(); ++i)
    bearings[i] = camera_.bearing(features.keypoints[i].x, features.keypoints[i].y);
  return true;
}

bool VisualGyro::estimatePair(const cv::Mat& gray, double stamp, FrameResult* result) {
  const double dt = stamp - previous_stamp_;
  result->dt = dt;
  const RotationPrior prior = prior_.priorFor(dt);
  FrameTimes& times = result->times;
  try {
    const auto t0 = std::chrono::steady_clock::now();
    matchFrames(prior);
    times.match += elapsedMs(t0);
    alignMatches(gray, &times);
    matchHalfResolution(gray, &times);
  } catch (const std::exception& e) {
    // Before any state changed: the frame is rejected, the previous one stays.
    result->status = FrameStatus::kFrontEndFailed;
    result->reason = std::string("front end failed: ") + e.what();
    return false;
  }
  collectMatches(result);
  if (settings_.run_estimator) {
    estimateRotation(gray, prior, dt, result);
  } else {
    result->status = FrameStatus::kNotEstimated;
    result->reason = "run_estimator is off: matches only";
  }
  result->matching = half_resolution_used_ ? PairMatching::kGlobal : matching_;
  result->half_resolution = half_resolution_used_;
  return true;
}

void VisualGyro::alignMatches(const cv::Mat& gray, FrameTimes* times) {
  const auto t0 = std::chrono::steady_clock::now();
  front_end_.refineMatches(previous_gray_, gray, previous_features_, features_, &matches_);
  front_end_.trackUnmatched(previous_gray_, gray, previous_features_, features_, matches_, &tracks_);
  times->align += elapsedMs(t0);
}

void VisualGyro::estimateRotation(const cv::Mat& gray, const RotationPrior& prior, double dt,
                                  FrameResult* result) {
  result->rotation = estimateAtBestResolution(prior, result);
  if (!result->rotation.valid() && matching_ == PairMatching::kGuided) fallBackToGlobal(gray, prior, result);
  if (result->rotation.valid()) {
    const std::string implausible = checkRatePlausible(result->rotation.rotation_vector, dt, settings_);
    if (!implausible.empty()) result->rotation.invalidate(FrameStatus::kImplausibleRate, implausible);
  }
  // An implausible rotation is no prior for the next frame either.
  prior_.update(result->rotation, dt);
  updatePriorUncertainty(prior, result->rotation);
  updateSearchParallax(*result);
  checkCalibrationFit(result);
  result->status = result->rotation.status;
  result->reason = result->rotation.reason;
  if (result->hasEstimate()) {
    result->angular_velocity = result->rotation.rotation_vector / dt;
    result->angular_velocity_covariance = result->rotation.covariance / (dt * dt);
  }
  result->times.estimate = result->rotation.times.estimate;
}

void VisualGyro::fallBackToGlobal(const cv::Mat& gray, const RotationPrior& prior, FrameResult* result) {
  // Guided matches that give no estimate: the prior may have sent the search to the wrong
  // place (plenty of chance matches there, few consistent). Global matching does not
  // depend on it; its estimate replaces the guided one, and both estimates' times count.
  const EstimateTimes guided_times = result->rotation.times;
  const auto t0 = std::chrono::steady_clock::now();
  front_end_.match(previous_features_, features_, &matches_);
  result->times.match += elapsedMs(t0);
  alignMatches(gray, &result->times);
  matchHalfResolution(gray, &result->times);
  matching_ = PairMatching::kGlobalFallback;
  collectMatches(result);
  result->rotation = estimateAtBestResolution(prior, result);
  result->rotation.times += guided_times;
}

void VisualGyro::keepAsPrevious(const cv::Mat& gray, double stamp) {
  has_previous_ = true;
  previous_stamp_ = stamp;
  gray.copyTo(previous_gray_);
  // Swapped, not moved: the old previous frame's buffers serve the next frame.
  std::swap(previous_features_, features_);
  std::swap(previous_keypoint_bearings_, bearings_);
  half_previous_ready_ = half_current_ready_;
  if (half_current_ready_) {
    std::swap(half_previous_gray_, half_gray_);
    std::swap(half_previous_features_, half_features_);
  }
}

void VisualGyro::collectMatches(FrameResult* result) const {
  result->previous_pixels.clear();
  result->current_pixels.clear();
  result->previous_bearings.clear();
  result->current_bearings.clear();
  if (half_resolution_used_) {
    // Half-resolution pixel p covers full-resolution pixels 2p and 2p + 1 (an exact 2 x 2 area
    // average), so its centre is at 2p + 0.5.
    auto full = [](const cv::Point2f& p) { return cv::Point2f(2.f * p.x + 0.5f, 2.f * p.y + 0.5f); };
    auto add = [&](const cv::Point2f& previous, const cv::Point2f& current) {
      const cv::Point2f p = full(previous), c = full(current);
      result->previous_pixels.push_back(p);
      result->current_pixels.push_back(c);
      result->previous_bearings.push_back(camera_.bearing(p.x, p.y));
      result->current_bearings.push_back(camera_.bearing(c.x, c.y));
    };
    for (const FeatureMatch& m : half_matches_) {
      add(half_previous_features_.keypoints[m.previous], half_features_.keypoints[m.current] + m.offset);
    }
    result->tracked = static_cast<int>(half_tracks_.size());
    for (const TrackedCorner& t : half_tracks_) add(half_previous_features_.keypoints[t.previous], t.position);
    return;
  }
  for (const FeatureMatch& m : matches_) {
    result->previous_pixels.push_back(previous_features_.keypoints[m.previous]);
    result->previous_bearings.push_back(previous_keypoint_bearings_[m.previous]);
    if (m.offset.x == 0.f && m.offset.y == 0.f) {
      result->current_pixels.push_back(features_.keypoints[m.current]);
      result->current_bearings.push_back(bearings_[m.current]);
    } else {
      // Sub-pixel position of the match (refineMatches()).
      const cv::Point2f pixel = features_.keypoints[m.current] + m.offset;
      result->current_pixels.push_back(pixel);
      result->current_bearings.push_back(camera_.bearing(pixel.x, pixel.y));
    }
  }
  result->tracked = static_cast<int>(tracks_.size());
  for (const TrackedCorner& t : tracks_) {
    result->previous_pixels.push_back(previous_features_.keypoints[t.previous]);
    result->previous_bearings.push_back(previous_keypoint_bearings_[t.previous]);
    result->current_pixels.push_back(t.position);
    result->current_bearings.push_back(camera_.bearing(t.position.x, t.position.y));
  }
}

RotationResult VisualGyro::estimateAtBestResolution(const RotationPrior& prior, FrameResult* result) {
  half_resolution_used_ = false;
  RotationResult full = estimator_->estimate(result->previous_bearings, result->current_bearings, prior);
  if (!half_matched_) return full;
  std::swap(result->previous_pixels, full_previous_pixels_);
  std::swap(result->current_pixels, full_current_pixels_);
  std::swap(result->previous_bearings, full_previous_bearings_);
  std::swap(result->current_bearings, full_current_bearings_);
  const int full_tracked = result->tracked;
  half_resolution_used_ = true;
  collectMatches(result);
  // A half-resolution descriptor patch spans twice the angle of a full-resolution one.
  estimator_->setMatchFootprint(2.0 * matchFootprint(camera_));
  RotationResult half = estimator_->estimateSameFrame(result->previous_bearings, result->current_bearings, prior);
  estimator_->setMatchFootprint(matchFootprint(camera_));
  half.times += full.times;
  // The estimate the data pin down better, by both its support and its covariance. A match count
  // alone cannot tell: at half resolution a sharp corner is located about half as precisely, so
  // four times as many matches would only break even, while under motion blur the full-resolution
  // corners are no better located than the half-resolution ones and far fewer survive (fewer than
  // a third as many on a rendered 15 px blur, with three to six times the half-resolution
  // estimate's standard deviation). The covariance alone cannot tell either: on a handful of
  // inliers it is itself a noisy estimate, and the smaller of two noisy covariances is the one more
  // likely too small (in heavy image noise the half-resolution pair keeps fewer inliers, not more).
  if (half.valid() && (!full.valid() || (half.inliers >= full.inliers &&
                                         half.covariance.trace() < full.covariance.trace()))) {
    return half;
  }
  half_resolution_used_ = false;
  std::swap(result->previous_pixels, full_previous_pixels_);
  std::swap(result->current_pixels, full_current_pixels_);
  std::swap(result->previous_bearings, full_previous_bearings_);
  std::swap(result->current_bearings, full_current_bearings_);
  result->tracked = full_tracked;
  full.times = half.times;
  return full;
}

void VisualGyro::matchHalfResolution(const cv::Mat& gray, FrameTimes* times) {
  // Without the estimator there is nothing to choose the resolution by.
  if (half_matched_ || !settings_.run_estimator) return;
  const int below = settings_.front_end.half_resolution_below;
  const size_t full_count = matches_.size() + tracks_.size();
  if (full_count >= static_cast<size_t>(below)) return;
  const int half_cols = gray.cols / 2, half_rows = gray.rows / 2;
  if (half_cols < kMinImageSide || half_rows < kMinImageSide) return;
  // An odd last row or column is left out, so that every half-resolution pixel is the mean of
  // exactly 2 x 2 pixels (collectMatches() maps positions back by that).
  const cv::Rect even(0, 0, 2 * half_cols, 2 * half_rows);
  auto features = [&](const cv::Mat& image, cv::Mat* half, FrameFeatures* out) {
    auto t0 = std::chrono::steady_clock::now();
    cv::resize(image(even), *half, cv::Size(half_cols, half_rows), 0.0, 0.0, cv::INTER_AREA);
    half_front_end_.detect(*half, &half_corners_);
    times->detect += elapsedMs(t0);
    t0 = std::chrono::steady_clock::now();
    half_front_end_.describe(*half, half_corners_, out);
    times->describe += elapsedMs(t0);
  };
  // The previous image's half-resolution features are reused when its own pair computed them.
  if (!half_previous_ready_) {
    features(previous_gray_, &half_previous_gray_, &half_previous_features_);
    half_previous_ready_ = true;
  }
  if (!half_current_ready_) {
    features(gray, &half_gray_, &half_features_);
    half_current_ready_ = true;
  }
  auto t0 = std::chrono::steady_clock::now();
  half_front_end_.match(half_previous_features_, half_features_, &half_matches_);
  times->match += elapsedMs(t0);
  t0 = std::chrono::steady_clock::now();
  half_front_end_.refineMatches(half_previous_gray_, half_gray_, half_previous_features_, half_features_,
                                &half_matches_);
  half_front_end_.trackUnmatched(half_previous_gray_, half_gray_, half_previous_features_, half_features_,
                                 half_matches_, &half_tracks_);
  times->align += elapsedMs(t0);
  half_matched_ = !half_matches_.empty() || !half_tracks_.empty();
}

void VisualGyro::matchFrames(const RotationPrior& prior) {
  const FrontEndSettings& s = settings_.front_end;
  if (s.matching != MatchingMode::kGuided || !prior.valid) {
    front_end_.match(previous_features_, features_, &matches_);
    matching_ = PairMatching::kGlobal;
    return;
  }
  const Eigen::Matrix3d rotation = so3Exp(prior.rotation_vector);
  front_end_.predict(camera_, rotation, prior_uncertainty_rad_ + search_parallax_rad_,
                     previous_keypoint_bearings_, &prediction_);
  front_end_.matchGuided(previous_features_, features_, prediction_, &matches_);
  matching_ = PairMatching::kGuided;
  // Too few: the prior is probably wrong (a jolt, a bad last estimate); global matching does not
  // depend on it.
  if (static_cast<int>(matches_.size()) < s.guided_min_matches) {
    front_end_.match(previous_features_, features_, &matches_);
    matching_ = PairMatching::kGlobalFallback;
  }
}

void VisualGyro::updatePriorUncertainty(const RotationPrior& prior, const RotationResult& estimate) {
  if (!estimate.valid()) {
    // The next frame has no prior (global matching); the uncertainty is set again once it has.
    prior_uncertainty_rad_ = 0.0;
    return;
  }
  // How far the constant-rate prediction was off this time (from identity when there was no
  // prior), plus three standard deviations of the estimate the next prior is made from.
  const Eigen::Vector3d predicted = prior.valid ? prior.rotation_vector : Eigen::Vector3d::Zero();
  const double error = rotationAngleBetween(so3Exp(predicted), estimate.rotation);
  const double sigma = std::sqrt(std::max(0.0, estimate.covariance.diagonal().maxCoeff()));
  prior_uncertainty_rad_ = std::isfinite(error + sigma) ? error + 3.0 * sigma : 0.0;
}

void VisualGyro::updateSearchParallax(const FrameResult& result) {
  search_parallax_rad_ = 0.0;
  const size_t n = result.previous_bearings.size();
  if (!result.rotation.valid() || n == 0) return;
  // A match's parallax is its angle from where the rotation alone puts it: the translation times
  // the point's inverse depth. The guided search predicts with the rotation alone, so a match
  // further than the search radius from its prediction is lost, the nearest points first, though
  // they are the ones that tell rotation from translation near structure. The next search
  // therefore also covers the last pair's parallax: its median over the matches (wrong matches,
  // far off, do not move it), doubled to reach points up to twice the median inverse depth. Under
  // forward motion guided_radius_growth already covers most of it; there this only widens the
  // search a little.
  constexpr double kParallaxCover = 2.0;
  const Eigen::Matrix3d& rotation = result.rotation.rotation;
  parallax_scratch_.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d predicted = rotation.transpose() * result.previous_bearings[i];
    const Eigen::Vector3d& current = result.current_bearings[i];
    parallax_scratch_[i] = std::atan2(predicted.cross(current).norm(), predicted.dot(current));
  }
  const auto median = parallax_scratch_.begin() + static_cast<std::ptrdiff_t>(n / 2);
  std::nth_element(parallax_scratch_.begin(), median, parallax_scratch_.end());
  if (std::isfinite(*median)) search_parallax_rad_ = kParallaxCover * *median;
}

void VisualGyro::checkCalibrationFit(FrameResult* result) {
  RotationResult& rotation = result->rotation;
  // The paper method models no translation: a moving camera's parallax, shared by neighbours,
  // would read as a calibration error.
  if (!rotation.valid() || settings_.estimator.method != EstimationMethod::kVote) return;
  result->residual_correlation = residual_correlation_.compute(
      result->previous_bearings, result->current_bearings, rotation.rotation, rotation.translation,
      1.0 / camera_.fx(), settings_.estimator.inlier_threshold_deg * kDegToRad, rotation.diagnostics.row_skew);
  calibration_fit_.add(result->residual_correlation);
  // Neither a rolling shutter nor a calibration that does not fit the images can be told apart by
  // the residuals alone, and under a rolling shutter the estimates stay good: the estimate is kept
  // with the covariance its correlated errors allow.
  if (!calibration_fit_.mismatch()) return;
  rotation.covariance *= calibration_fit_.covarianceInflation();
  result->calibration_mismatch = calibration_fit_.describe();
}

}  // namespace visual_gyro
