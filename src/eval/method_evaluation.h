// One method run over the frame pairs and scored by the metrics module: per-frame rows (the
// diagnostics CSV) and the summary `evaluate` prints as text and as one JSON line.
#pragma once

#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "frame_pairs.h"
#include "method_runners.h"
#include "metrics.h"
#include "visual_gyro/imu_alignment.h"

namespace visual_gyro {
namespace eval {

/// One frame of one method.
struct FrameRow {
  size_t frame = 0;
  int matches = 0;
  bool valid = false;
  double estimate_ms = 0.0;
  metrics::FrameEstimate estimate;  ///< what the method gave, as the metrics module scores it
  metrics::FrameErrors errors;  ///< scored as the metrics module does (invalid = identity)
  double sigma_deg = std::numeric_limits<double>::quiet_NaN();  ///< sqrt(trace C) [deg]
  /// Standard deviations the covariance gives each axis [deg].
  Eigen::Vector3d sigma_axes_deg = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  int inliers = -1;
  bool pure_rotation = false;
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  ///< MethodEstimate::translation
  VoteDiagnostics diagnostics;
  bool half_resolution = false;  ///< the pair's matches came from half resolution (FramePair)
  double residual_correlation = std::numeric_limits<double>::quiet_NaN();  ///< MethodEstimate's
  std::string error;
};

/// One method over all pairs.
struct MethodSummary {
  std::string method;
  Backend backend = Backend::kCpu;
  std::vector<FrameRow> rows;
  metrics::AccuracySummary accuracy;
  double detect = 0, describe = 0, match = 0, align = 0, estimate = 0, total = 0;  ///< mean ms per frame
  double vote = 0, vote_device = 0, refine = 0;  ///< mean ms per frame; NaN for the baselines
  double matches_mean = 0;
  double true_translation_mean = std::numeric_limits<double>::quiet_NaN();  ///< [m] (poses)
  std::string first_error;
  std::string front_end;  ///< native, orb or klt
  /// Native front end: the matching setting; empty for a comparison front end.
  std::optional<MatchingMode> matching;
  double tracked_mean = 0;  ///< native: tracked corners per pair (FrontEndSettings::track_unmatched)
  int guided_pairs = 0;   ///< native: pairs matched guided by the prior
  int fallback_pairs = 0;  ///< native: pairs where guided matching fell back to global
  int half_resolution_pairs = 0;  ///< native: pairs matched at half resolution (starved at full)
  /// vote: median of the rows' residual_correlation, and the largest median over
  /// kFitWindowFrames consecutive judged rows (what the calibration check compares with
  /// kFitMismatchCorrelation); NaN for the other methods.
  double residual_correlation_median = std::numeric_limits<double>::quiet_NaN();
  double residual_correlation_window_max = std::numeric_limits<double>::quiet_NaN();
};

/// Runs `runner` over `pairs` in order: every row's estimate, times and diagnostics, not scored.
MethodSummary runMethod(const std::string& method, MethodRunner* runner, const std::vector<FramePair>& pairs);
/// Scores every row of `summary` against the truth of its pair (rows in the pairs' order): the
/// rows' errors and the accuracy summary. Throws std::invalid_argument when the counts differ.
void scoreMethod(const std::vector<FramePair>& pairs, MethodSummary* summary);
/// runMethod, then scoreMethod.
MethodSummary evaluateMethod(const std::string& method, MethodRunner* runner, const std::vector<FramePair>& pairs);

/// For a sequence whose truth is its gyro (bias included, on the IMU's clock): aligns the gyro with
/// the estimates of summaries[reference] (alignImu; the sequence's camera-IMU rotation, EuRoC's
/// T_BS, taken as known; offset and bias estimated; a method without covariances counts each
/// frame as uncertain by one pixel), recomputes every pair's truth from the aligned gyro
/// (alignedGyro) and rescores every summary. Returns the alignment. Throws ImuAlignmentError when
/// the gyro cannot be aligned (too few valid frames, ...); nothing is changed then.
ImuAlignment alignGyroTruth(const Sequence& sequence, size_t reference, std::vector<FramePair>* pairs,
                            std::vector<MethodSummary>* summaries);

/// What a report says about the run besides the summary.
struct RunDescription {
  std::string dataset, layout, truth;  ///< the sequence's name, layout and reference kind
  double outliers = 0.0;               ///< injected outlier fraction
  double moving_region = 0.0;          ///< fraction of the matches moved as one object (moveRegion)
  double moving_deg = 0.0;             ///< that object's own rotation a pair [deg]
  ImageDegradation degradation;        ///< applied to the images before the front end
  double scale = 1.0;                  ///< images downscaled by this factor as read (Sequence::image_scale)
  int stride = 1;
  int hypotheses = 0;                  ///< per frame (vote, paper)
  /// For a gyro reference: the alignment removed from it (offset and bias); null when the gyro is
  /// scored as recorded, or the truth is not a gyro.
  const ImuAlignment* gyro_alignment = nullptr;
};

/// The readable summary of one method.
std::string summaryText(const RunDescription& run, const MethodSummary& summary);
/// The one-line JSON object of one method (the keys doc/evaluation.md documents).
std::string summaryJson(const RunDescription& run, const MethodSummary& summary);
/// Writes every method's per-frame rows as CSV; throws DataError when it cannot.
void writeFrameCsv(const std::string& path, const std::vector<MethodSummary>& all);

}  // namespace eval
}  // namespace visual_gyro
