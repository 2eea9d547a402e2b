// Whether the camera model fits the images, judged from the residuals of the estimated motion.
//
// A wrong calibration (distortion, principal point) bends every bearing by an error that changes
// smoothly over the image; the estimated motion absorbs part of it and leaves the rest in the
// residuals, where neighbouring matches share it. Pixel noise, blur and compression leave
// residuals that are independent from one match to the next, however large. So the check is the
// correlation of the residuals of neighbouring matches, which does not grow with image noise.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace visual_gyro {

/// Nearest other match whose residual is paired with a match's, as a separation on the image
/// [px]: at least kFitMinSeparationPx, more than the sub-pixel alignment's window (11 px), so that
/// the two corners are located from different pixels and their location errors are independent
/// (closer matches' residuals correlate without any calibration error: 0.42 instead of 0.18 on
/// euroc_mh01_shake); at most kFitMaxSeparationPx, so that both see about the same calibration
/// error.
constexpr double kFitMinSeparationPx = 16.0;
constexpr double kFitMaxSeparationPx = 48.0;
/// Residuals beyond this many inlier gates are wrong matches and stay out of the correlation.
constexpr double kFitResidualGates = 3.0;
/// Fewer neighbour pairs than this: the frame's correlation is not judged (NaN).
constexpr int kFitMinPairs = 30;
/// Matches used per frame at most (every k-th of the list when there are more).
constexpr size_t kFitMaxMatches = 400;

/// Frames (with a judged correlation) over which the calibration is judged.
constexpr size_t kFitWindowFrames = 20;
/// Median correlation over the window from which the calibration does not fit. Measured with
/// evaluate's residual_correlation (vote, default settings, CPU; 2026-12-04), largest 20-frame
/// median: shared sequences 0.28 (euroc_mh01_shake), 0.17 (kitti_turn), 0.06 and 0.04; rendered
/// sequences (five presets, 320x240, noise 8, blur 15 px, JPEG 30) 0.10 at most; kitti_turn,
/// kitti_straight and euroc_mh01_shake at 10 % contrast with noise 3, 5 % contrast, noise 8 or
/// JPEG 20: 0.23 at most. A rolling shutter correlates neighbours too, and its estimates are still
/// good: the rendered hand-held room with a 28 ms read-out reaches 0.41 at 0.026 deg RMSE, NEES 1.6,
/// hence 0.5 rather than a bound just above the global-shutter footage. Calibrations that do not
/// fit: euroc_mh01_shake without its distortion 0.45 to 0.72 over every window, with half of it
/// 0.37 to 0.64 (all 19 and 20 of 23 estimates before the first full window beyond 3 sigma); the
/// rendered pinhole camera given plumb_bob k1 = 0.3 reaches it within a window. Errors the
/// estimated motion absorbs hardly show: kitti_turn with the principal point 15 % off centre
/// reaches 0.39, with a focal length 20 % off 0.15 (most of their estimates beyond 3 sigma).
constexpr double kFitMismatchCorrelation = 0.5;
/// The most covarianceInflation() multiplies a covariance by (a median correlation of 0.905).
constexpr double kMaxFitInflation = 20.0;

/// The residual of one match under the motion (rotation R with b_prev ~ R b_cur, unit translation
/// t in the previous frame, zero for a pure rotation), as a vector [rad]: the distance of b_prev
/// from the epipolar plane of R b_cur along the plane's normal, or, without translation, b_prev -
/// R b_cur; with a rolling shutter's `row_skew`, R is the match's own rotation R exp(s row_skew)
/// (s = matchRow, geometry.h).
Eigen::Vector3d motionResidual(const Eigen::Vector3d& previous, const Eigen::Vector3d& current,
                               const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation,
                               const Eigen::Vector3d& row_skew = Eigen::Vector3d::Zero());

/// Correlation in [-1, 1] of the residual vectors (motionResidual) of neighbouring matches: each
/// match with its nearest other match between kFitMinSeparationPx and kFitMaxSeparationPx away
/// (angles between the current bearings, `pixel_angle_rad` radians per pixel), residuals beyond
/// kFitResidualGates * `gate_rad` left out. About 0 when the residuals are pixel noise, towards 1
/// when they are a smooth error shared by neighbours. NaN with fewer than kFitMinPairs pairs.
/// Not thread-safe (reuses its buffers); one per stream.
class ResidualCorrelation {
 public:
  /// `row_skew`: a pure rotation's rolling-shutter skew (VoteDiagnostics::row_skew), so that what
  /// the skew explains is no residual.
  double compute(const std::vector<Eigen::Vector3d>& previous, const std::vector<Eigen::Vector3d>& current,
                 const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation, double pixel_angle_rad,
                 double gate_rad, const Eigen::Vector3d& row_skew = Eigen::Vector3d::Zero());

 private:
  struct Point {
    long long cell;           ///< key of the 3-D grid cell of the current bearing
    Eigen::Vector3d bearing;  ///< current bearing
    Eigen::Vector3d residual;
  };
  std::vector<Point> points_;
};

/// Judges the calibration over the last kFitWindowFrames frames' correlations (ResidualCorrelation):
/// it does not fit while their median is kFitMismatchCorrelation or more. Not thread-safe; one per
/// stream.
class CalibrationFitMonitor {
 public:
  /// Adds one frame's correlation; NaN (not judged) is ignored.
  void add(double correlation);
  /// True once the window is full and its median reaches kFitMismatchCorrelation.
  bool mismatch() const;
  /// Frames in the window (at most kFitWindowFrames).
  size_t frames() const { return window_.size(); }
  /// Median of the window (NaN while empty).
  double median() const;
  /// The factor by which an estimate's covariance is multiplied while the calibration does not fit,
  /// 1 otherwise: (1 + rho) / (1 - rho) with rho the window's median correlation, at most
  /// kMaxFitInflation. Matches whose errors correlate between neighbours by rho carry about
  /// n (1 - rho) / (1 + rho) independent ones' worth (the effective sample size of a first-order
  /// autoregressive series).
  double covarianceInflation() const;
  /// Why the calibration does not fit, with the numbers (for the frames' status and /diagnostics).
  std::string describe() const;
  /// Forgets every frame (a new camera model).
  void reset() { window_.clear(); }

 private:
  std::vector<double> window_;  ///< oldest first
  mutable std::vector<double> sorted_;  ///< median()'s copy of the window, reused
};

}  // namespace visual_gyro
