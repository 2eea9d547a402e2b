// One method run over the frame pairs and scored by the metrics module: per-frame rows (the
// diagnostics CSV) and the summary `evaluate` prints as text and as one JSON line.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "frame_pairs.h"
#include "method_runners.h"
#include "metrics.h"

namespace visual_gyro {
namespace eval {

/// One frame of one method.
struct FrameRow {
  size_t frame = 0;
  int matches = 0;
  bool valid = false;
  double estimate_ms = 0.0;
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
  std::string method, backend;
  std::vector<FrameRow> rows;
  metrics::AccuracySummary accuracy;
  double detect = 0, describe = 0, match = 0, align = 0, estimate = 0, total = 0;  ///< mean ms per frame
  double vote = 0, vote_device = 0, refine = 0;  ///< mean ms per frame; NaN for the baselines
  double matches_mean = 0;
  double true_translation_mean = std::numeric_limits<double>::quiet_NaN();  ///< [m] (poses)
  std::string first_error;
  std::string front_end;  ///< native, orb or klt
  std::string matching;   ///< native: the matching setting (guided, global); else ""
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

/// Runs `runner` over `pairs` in order and scores every frame.
MethodSummary evaluateMethod(const std::string& method, MethodRunner* runner, const std::vector<FramePair>& pairs);

/// What a report says about the run besides the summary.
struct RunDescription {
  std::string dataset, layout, truth;  ///< the sequence's name, layout and reference kind
  double outliers = 0.0;               ///< injected outlier fraction
  ImageDegradation degradation;        ///< applied to the images before the front end
  int stride = 1;
  int hypotheses = 0;                  ///< per frame (vote, paper)
};

/// The readable summary of one method.
std::string summaryText(const RunDescription& run, const MethodSummary& summary);
/// The one-line JSON object of one method (the keys the README documents).
std::string summaryJson(const RunDescription& run, const MethodSummary& summary);
/// Writes every method's per-frame rows as CSV; throws DataError when it cannot.
void writeFrameCsv(const std::string& path, const std::vector<MethodSummary>& all);

}  // namespace eval
}  // namespace visual_gyro
