// Frame pairs: a sequence run through a front end once, so that every estimation method sees
// exactly the same matches. With the reference each pair has (poses or gyro).
#pragma once

#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "metrics.h"
#include "visual_gyro/renderer.h"
#include "visual_gyro/sequence.h"
#include "visual_gyro/visual_gyro.h"

namespace visual_gyro {
namespace eval {

/// A problem with the data (missing folder, unreadable image, unusable calibration): exit status 1.
struct DataError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// One pair of images (previous_index, index) and its matches.
struct FramePair {
  size_t previous_index = 0;  ///< image index of the previous frame
  size_t index = 0;           ///< image index of the current frame
  double dt = 0.0;            ///< [s]
  std::vector<Eigen::Vector3d> previous, current;  ///< matched bearings (after max_matches/outliers)
  FrameTimes front_end;       ///< detect, describe, match of the current frame [ms]
  /// Native front end: how the pair was matched (FrameResult::matching); kNone for the others.
  PairMatching matching = PairMatching::kNone;
  int tracked = 0;            ///< native front end: pairs that are tracked corners (before subsampling)
  bool half_resolution = false;  ///< native front end: matched at half resolution (FrameResult)
  /// kFrozenImage (bit-identical to the previous image) or kNoTexture when the current image gave
  /// no matches and left the previous one in place; kValid for a usable image.
  FrameStatus image_status = FrameStatus::kValid;
  /// Why the image was unusable, for people, as "<frame status>: <reason>"; "" for a usable image.
  std::string unusable_image;
  metrics::FrameTruth truth;  ///< the pair's reference
  double true_translation = std::numeric_limits<double>::quiet_NaN();  ///< camera displacement [m] (poses)
};

/// How the pairs are made.
struct FramePairOptions {
  long long frames = -1;          ///< at most this many pairs (-1: all)
  int stride = 1;                 ///< pair image k with image k - stride
  int max_matches = 0;            ///< a deterministic random subset of at most this many (0: all)
  double outliers = 0.0;          ///< fraction of matches replaced by wrong pairings
  /// Fraction of the matches that move as one independent object (moveRegion; 0: none), and that
  /// object's own rotation a pair [deg].
  double moving_region = 0.0;
  double moving_deg = 0.5;
  uint64_t seed = 1;              ///< seed of the subset and the outliers
  std::string front_end = "native";  ///< native, or a comparison front end (orb, klt)
  /// Applied to every image as it is read (after the sequence's own downscaling, image_scale),
  /// before any front end sees it (its noise drawn from `seed` and the image's index, so every
  /// method and front end sees the same images).
  ImageDegradation degradation;
  bool quiet = false;             ///< no progress on stderr
};

/// Runs the front end over the sequence: one FramePair per (k - stride, k). The native front end
/// runs the pipeline; with guided matching its own vote estimator runs too (on the CPU, not timed
/// into any method), because the rotation prior that guides the matching comes from it, as in the
/// node. orb and klt give pixels, turned into bearings through the sequence's camera model.
/// Throws DataError for unusable images or when no pair is left.
std::vector<FramePair> collectFramePairs(const Sequence& sequence, const VisualGyroSettings& settings,
                                         const FramePairOptions& options);

/// The pair's reference from the sequence's truth (its truth field and true_translation): the
/// composed frame-to-frame rotations between its images and, for a gyro or EuRoC poses, the
/// dt-weighted mean rate.
void fillPairTruth(const Sequence& sequence, FramePair* pair);

/// Moves the fraction `fraction` of the matches as one independently moving object would: those
/// furthest right in the previous image (largest atan2(x, z), optical frame) get their current bearings
/// turned by `angle_deg` about the camera's y axis, a sideways motion in the image of their own
/// beside the camera's. Deterministic; the other matches are untouched.
void moveRegion(double fraction, double angle_deg, FramePair* pair);

/// Keeps a deterministic random subset of at most max_matches matches.
void subsampleMatches(int max_matches, uint64_t seed, FramePair* pair);

/// Writes the pairs' bearings (and truth) as a bearing file (see bearing_file.h).
void exportBearings(const std::vector<FramePair>& pairs, const std::string& path);

}  // namespace eval
}  // namespace visual_gyro
