// The visual gyroscope pipeline: gray image in, frame-to-frame rotation and angular velocity out.
// ROS-free; the nodelet (src/ros/) and the evaluation command both drive it.
#pragma once

#include <limits>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "visual_gyro/backend.h"
#include "visual_gyro/calibration_fit.h"
#include "visual_gyro/camera_model.h"
#include "visual_gyro/feature_front_end.h"
#include "visual_gyro/frame_status.h"
#include "visual_gyro/rotation_estimator.h"

namespace visual_gyro {

/// Wall-clock time of each stage of a frame [ms].
struct FrameTimes {
  double detect = 0.0;    ///< FAST corners and their bucketing
  double describe = 0.0;  ///< smoothing and BRIEF descriptors
  /// Descriptor matching (guided, global, and global again when guided matching gave no
  /// estimate).
  double match = 0.0;
  /// Sub-pixel alignment: refinement of the matches and tracking of unmatched corners
  /// (refineMatches() and trackUnmatched(); 0 when both are off).
  double align = 0.0;
  /// The rotation estimates of the frame (two when guided matching fell back to global); their
  /// parts are in FrameResult::rotation.times.
  double estimate = 0.0;
  double total = 0.0;  ///< the whole frame, checks included
};

/// How a frame was paired with the previous one (FrameResult::matching).
enum class PairMatching {
  kNone,            ///< not matched (first frame, rejected image)
  kGuided,          ///< around where the rotation prior predicts each corner
  kGlobal,          ///< every descriptor against every other (no prior, matching = global)
  /// Global after guided matching found too few matches or its matches gave no valid estimate.
  kGlobalFallback,
};

/// The text of a PairMatching as logs and docs name it: "" (kNone), "guided", "global",
/// "global_fallback".
const char* pairMatchingName(PairMatching matching);
/// Writes pairMatchingName(matching).
std::ostream& operator<<(std::ostream& out, PairMatching matching);

/// What the pipeline produced for one image.
struct FrameResult {
  /// kValid when the frame has an estimate; otherwise why not (see frame_status.h). Skipped
  /// statuses (frameSkipped) leave the pipeline's state untouched; kFrozenImage and kNoTexture keep
  /// the previous image and its stamp.
  FrameStatus status = FrameStatus::kNotEstimated;
  std::string reason;  ///< details for people ("" when valid)
  /// True when status is kValid: rotation and angular_velocity hold an estimate.
  bool hasEstimate() const { return status == FrameStatus::kValid; }
  /// True when the frame was not used (see frameSkipped).
  bool skipped() const { return frameSkipped(status); }
  FrameTimes times;                 ///< this frame's stage times
  RotationResult rotation;          ///< frame-to-frame rotation (previous -> this frame)
  double dt = 0.0;                  ///< this stamp - previous stamp [s]
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  ///< rotation vector / dt [rad/s]
  /// Covariance of angular_velocity [(rad/s)^2] = rotation covariance / dt^2.
  Eigen::Matrix3d angular_velocity_covariance = Eigen::Matrix3d::Identity();
  int features = 0;                 ///< keypoints described in this frame
  /// How this frame was matched: kGuided (around the rotation prior's prediction), kGlobal (no
  /// prior, matching = global, or the half-resolution matches were kept), kGlobalFallback (guided
  /// found too few matches, or its matches gave no valid estimate); kNone when not matched (first
  /// frame, rejected image).
  PairMatching matching = PairMatching::kNone;
  /// Of the pairs below, how many are tracked corners (FrontEndSettings::track_unmatched); they
  /// come after the descriptor matches.
  int tracked = 0;
  /// The pairs below come from both images at half resolution, matched globally: the
  /// full-resolution pair gave fewer than FrontEndSettings::half_resolution_below matches, and the
  /// estimate from the half-resolution pairs was the better one (valid where the full-resolution
  /// one is not, or as many inliers or more and a smaller covariance). Their pixels are
  /// full-resolution coordinates all the same.
  bool half_resolution = false;
  /// Correlation of the estimate's residuals between neighbouring matches (ResidualCorrelation;
  /// vote method, NaN otherwise or when too few matches): near 0 when the camera model fits the
  /// images. Over the last kFitWindowFrames frames it decides calibration_mismatch.
  double residual_correlation = std::numeric_limits<double>::quiet_NaN();
  /// Non-empty (why, with the numbers) while the residuals of neighbouring matches say the camera
  /// model does not fit the images (CalibrationFitMonitor): the estimate's covariance is then
  /// multiplied by CalibrationFitMonitor::covarianceInflation().
  std::string calibration_mismatch;
  /// Matched pixels (previous, current) and their bearings, in match order; what the estimator saw.
  std::vector<cv::Point2f> previous_pixels, current_pixels;
  std::vector<Eigen::Vector3d> previous_bearings, current_bearings;
};

/// Settings of the whole pipeline. Ranges, units and docs: visualGyroSettingFields().
struct VisualGyroSettings {
  FrontEndSettings front_end;
  EstimatorSettings estimator;
  /// false: front end only; FrameResult then holds the matches but no rotation (used to run
  /// baseline estimators on exactly the same matches). An option of the evaluation (`evaluate`,
  /// frame_pairs), not a setting: not in the settings table, the cfg, the yaml or the docs.
  bool run_estimator = true;
  /// [s] A time step below this is skipped (the frame is not used): no camera delivers frames
  /// this close, so such a stamp is wrong and a rate computed over it would be huge.
  double min_dt = 1e-3;
  /// [deg/s] An estimated angular rate above this is reported invalid (the full scale of common
  /// MEMS gyros; far beyond what a camera image survives without motion blur).
  double max_rate_dps = 2000.0;
};

/// Every setting of the pipeline (front end, estimator and its own), each defined once with its
/// range, unit, doc, tier and whether it changes live. The names are unique across the three.
const std::vector<SettingField<VisualGyroSettings>>& visualGyroSettingFields();

/// The setting called `name`, or nullptr.
const SettingField<VisualGyroSettings>* findSetting(const std::string& name);

/// Sets one setting from text (as `evaluate --set name=value`, the nodelet's start-up parameters
/// and dynamic_reconfigure do): "" when `value` parses and is accepted, else why, naming the
/// setting (and *settings is unchanged). NaN and infinities are never accepted.
std::string applySetting(VisualGyroSettings* settings, const std::string& name, const std::string& value);

/// The settings as Markdown tables (setting, default, accepted values, live or at start, meaning),
/// one per tier: user, expert, paper-only, each under a bold label; `evaluate --settings-table`
/// prints it, and doc/ros.md holds it between its settings-table markers.
std::string settingsMarkdownTable();

/// "" when the settings are usable: every setting in its range (there are no rules across
/// settings); else a message naming the setting.
std::string validateVisualGyroSettings(const VisualGyroSettings& settings);

/// "" when a rotation vector [rad] over dt [s] is a plausible rate for `settings`, else why not
/// (the rate above max_rate_dps, or dt not positive). Applied to every estimate before it is
/// reported, by the pipeline and by the evaluation of other methods.
std::string checkRatePlausible(const Eigen::Vector3d& rotation_vector, double dt,
                               const VisualGyroSettings& settings);

/// Angle [rad] the front end's descriptor patch (2 kBriefHalfPatch + 1 pixels) spans in the images
/// of `camera` at its principal point, along the axis of the shorter focal length:
/// (2 kBriefHalfPatch + 1) / min(fx, fy). What the vote method checks its inliers' spread against
/// (RotationEstimator::setMatchFootprint).
double matchFootprint(const CameraModel& camera);

/// Grey-level standard deviation [grey levels] below which an image has no texture (FrameStatus::
/// kNoTexture): all-black and all-white (clipped) images have 0; the least textured images the
/// pipeline still estimates have more: kitti_turn's frames dimmed to 5 % contrast 3.1, the
/// renderer's dim room 6. A flat image with sensor noise passes this check (its noise is its
/// standard deviation) and is then caught by having no corner, or gives too few matches.
constexpr double kMinTextureStdDev = 1.0;

/// Smallest image side the front end can describe a keypoint in: the BRIEF patch plus the
/// detector's border on both sides [px].
constexpr int kMinImageSide = 2 * (kBriefHalfPatch + 1) + 1;

/// Runs detection, description, matching and rotation estimation frame to frame.
/// Not thread-safe (one instance per image stream).
class VisualGyro {
 public:
  /// Throws std::invalid_argument when the camera or settings are unusable (message says why):
  /// CameraModel::validate() and calibrationProblem() must both pass.
  VisualGyro(const CameraModel& camera, const VisualGyroSettings& settings,
             const WarningSink& warn = WarningSink());

  /// Processes the next image (CV_8UC1; stamp in seconds). Never throws for bad images: returns a
  /// FrameResult whose status says why there is no estimate. A stamp not after the previous one, or
  /// less than min_dt after it, is rejected without touching the state (skipped); an image without
  /// texture (grey-level standard deviation below kMinTextureStdDev, or no corner found) is
  /// flagged kNoTexture, one identical to the previous one frozen (both keep the previous image);
  /// an estimated rate above max_rate_dps is invalid; while the calibration does not fit the images
  /// (CalibrationFitMonitor over the vote method's estimates) each estimate's covariance is
  /// inflated and FrameResult::calibration_mismatch says why.
  FrameResult processFrame(const cv::Mat& gray, double stamp);

  /// Forgets the previous frame (after a time jump or a camera change). The calibration check's
  /// recent frames stay: the camera is the same.
  void reset();
  /// Changes intrinsics (camera_info changed); resets, and the calibration check starts afresh.
  /// Throws std::invalid_argument when unusable (validate() or calibrationProblem() names a
  /// problem).
  void setCamera(const CameraModel& camera);
  /// Changes settings live; the backend stays.
  void setSettings(const VisualGyroSettings& settings);

  const CameraModel& camera() const { return camera_; }
  const VisualGyroSettings& settings() const { return settings_; }
  /// The backend that votes this pipeline's estimates, chosen once at construction.
  Backend backend() const { return backend_; }

 private:
  /// processFrame()'s checks, in this order, each leaving the state untouched: true (with the
  /// status and reason in `result`) when the image is unusable (kImageRejected: empty, not
  /// CV_8UC1, not the camera's size, smaller than kMinImageSide).
  bool rejectImage(const cv::Mat& gray, FrameResult* result) const;
  /// True when `stamp` [s] is not finite or not after the previous one (kStampRejected), or less
  /// than min_dt after it (kTimeStepTooSmall, dt set).
  bool rejectStamp(double stamp, FrameResult* result) const;
  /// True when the image has no texture (kNoTexture) or repeats the previous one (kFrozenImage);
  /// dt is set when there is a previous frame.
  bool rejectContent(const cv::Mat& gray, double stamp, FrameResult* result) const;
  /// Detects and describes `gray` into features_ and bearings_ (their stage times and the feature
  /// count into `result`); false (kFrontEndFailed, or kNoTexture without a corner) when the frame
  /// cannot be used.
  bool describeFrame(const cv::Mat& gray, double stamp, FrameResult* result);
  /// Matches the previous frame to this one and, when run_estimator, estimates their rotation
  /// into `result`; false (kFrontEndFailed) when the front end threw before any state changed.
  bool estimatePair(const cv::Mat& gray, double stamp, FrameResult* result);
  /// Sub-pixel refinement of matches_ and tracking of the unmatched corners into tracks_; adds
  /// its time to times->align.
  void alignMatches(const cv::Mat& gray, FrameTimes* times);
  /// Estimates the rotation over `dt` [s] from the matches in `result` (global matching again
  /// when guided matches gave no estimate), checks it (rate, calibration fit), updates the prior
  /// and the guided search, and sets the status, angular velocity and estimate time.
  void estimateRotation(const cv::Mat& gray, const RotationPrior& prior, double dt, FrameResult* result);
  /// Replaces guided matches that gave no estimate by global ones and estimates again; both
  /// estimates' times count.
  void fallBackToGlobal(const cv::Mat& gray, const RotationPrior& prior, FrameResult* result);
  /// Makes this frame (`gray` at `stamp` [s], its features and half-resolution data) the previous
  /// one.
  void keepAsPrevious(const cv::Mat& gray, double stamp);
  /// Matches previous_features_ to features_ into matches_: guided by `prior` when usable, else
  /// (or when guided finds too few) global. Sets matching_.
  void matchFrames(const RotationPrior& prior);
  /// Copies the pixels and bearings of matches_ (or of the half-resolution matches, when they are
  /// used) into `result` (in match order).
  void collectMatches(FrameResult* result) const;
  /// Matches the previous and the current image (`gray`) again at half resolution (globally) when
  /// the full-resolution pair is starved (FrontEndSettings::half_resolution_below); sets
  /// half_matched_ when that gave any match. Adds its stage times to `times`.
  void matchHalfResolution(const cv::Mat& gray, FrameTimes* times);
  /// Estimates from the matches in `result`; when there are half-resolution matches too, estimates
  /// from those as well (same frame seed) and keeps that estimate when it is valid and the
  /// full-resolution one is not, or when it has at least as many inliers and a smaller covariance
  /// trace, leaving the kept estimate's matches in `result` (half_resolution_used_ says which).
  /// Both estimates' times count.
  RotationResult estimateAtBestResolution(const RotationPrior& prior, FrameResult* result);
  /// Records how far `prior` was from `estimate` (see prior_uncertainty_rad_).
  void updatePriorUncertainty(const RotationPrior& prior, const RotationResult& estimate);
  /// Records how far the matches of `result` lie from where its estimated rotation alone puts
  /// them (search_parallax_rad_; 0 without an estimate).
  void updateSearchParallax(const FrameResult& result);
  /// Judges the calibration by the valid vote-method estimate in `result` (its
  /// residual_correlation), and invalidates the estimate while the calibration does not fit.
  void checkCalibrationFit(FrameResult* result);

  CameraModel camera_;
  VisualGyroSettings settings_;
  FeatureFrontEnd front_end_;
  std::unique_ptr<RotationEstimator> estimator_;
  Backend backend_ = Backend::kCpu;  // estimator_'s
  bool has_previous_ = false;
  double previous_stamp_ = 0.0;
  cv::Mat previous_gray_;  ///< the last used image (own copy), to detect a frozen camera
  FrameFeatures previous_features_;
  std::vector<Eigen::Vector3d> previous_keypoint_bearings_;
  PriorTracker prior_;
  /// How far the last prior was from that frame's estimate [rad] (identity counts as the prior
  /// when there was none): widens the guided search.
  double prior_uncertainty_rad_ = 0.0;
  /// Twice the last pair's median parallax [rad] (see updateSearchParallax()): widens the guided
  /// search too.
  double search_parallax_rad_ = 0.0;
  std::vector<double> parallax_scratch_;  // per-match parallax, reused
  ResidualCorrelation residual_correlation_;
  CalibrationFitMonitor calibration_fit_;
  PairMatching matching_ = PairMatching::kNone;  // how the last frame was matched (FrameResult::matching)
  // Per-frame buffers, reused (swapped with the previous frame's) so that the steady state does not
  // allocate in the front end.
  std::vector<cv::Point2f> corners_;
  FrameFeatures features_;
  std::vector<Eigen::Vector3d> bearings_;
  MatchPrediction prediction_;
  std::vector<FeatureMatch> matches_;
  std::vector<TrackedCorner> tracks_;  ///< unmatched previous corners found by tracking
  /// The half-resolution pass (matchHalfResolution()): its own front end (its buffers and
  /// detection state belong to half-resolution images), both images downsampled, their features,
  /// matches and tracks. The current frame's half-resolution image and features serve as the
  /// previous ones on the next frame when half_previous_ready_.
  FeatureFrontEnd half_front_end_;
  bool half_matched_ = false;          ///< this pair has half-resolution matches
  bool half_resolution_used_ = false;  ///< the estimate came from them
  bool half_current_ready_ = false;
  bool half_previous_ready_ = false;
  cv::Mat half_previous_gray_, half_gray_;
  std::vector<cv::Point2f> half_corners_;
  FrameFeatures half_previous_features_, half_features_;
  std::vector<FeatureMatch> half_matches_;
  std::vector<TrackedCorner> half_tracks_;
  /// The full-resolution matches while the half-resolution ones are estimated.
  std::vector<cv::Point2f> full_previous_pixels_, full_current_pixels_;
  std::vector<Eigen::Vector3d> full_previous_bearings_, full_current_bearings_;
};

}  // namespace visual_gyro
