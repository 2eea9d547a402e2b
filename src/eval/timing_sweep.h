// Timing sweep (make bench): estimation time of every method on the same frame pairs, over
// hypotheses and over matches, as the paper plots them.
#pragma once

#include <string>
#include <vector>

#include "baselines.h"
#include "frame_pairs.h"
#include "visual_gyro/visual_gyro.h"

namespace visual_gyro {
namespace eval {

/// What the sweep runs.
struct TimingSweepOptions {
  std::string csv_path;                 ///< where the CSV goes
  std::vector<std::string> methods;
  std::vector<int> hypotheses{100, 300, 1000, 3000, 10000, 30000, 100000};  ///< series "hypotheses"
  std::vector<int> matches{250, 500, 1000, 2000, 4000, 8000};               ///< series "matches"
  int at_matches = 2000;      ///< matches of the hypotheses series
  int at_hypotheses = 10000;  ///< hypotheses of the matches series
  int repeats = 3;            ///< runs per pair; the fastest counts
  uint64_t seed = 1;          ///< seed of the resampling
  /// The pairs' positions are sub-pixel (refinesPositions of their front end): the estimators'
  /// covariance model, and so their time, depends on it.
  bool refined_positions = false;
  /// The angle a match's descriptor patch spans [rad] (matchFootprint() of the camera): the vote
  /// method's check of its inliers' spread.
  double match_footprint = 0.0;
};

/// Two series: over hypotheses at a fixed number of matches (methods without a hypothesis count,
/// the OpenCV and OpenGV RANSACs, run once there with their own adaptive iteration count), and over
/// matches at a fixed number of hypotheses. Pairs with fewer matches than asked are topped up with
/// jittered copies (column real_fraction says how much was real). Prints a table to stdout; throws
/// DataError when the CSV cannot be written.
void timingSweep(const std::string& dataset, double pixel_angle, const TimingSweepOptions& options,
                 const VisualGyroSettings& settings, const BaselineSettings& baseline,
                 const std::vector<FramePair>& pairs);

}  // namespace eval
}  // namespace visual_gyro
