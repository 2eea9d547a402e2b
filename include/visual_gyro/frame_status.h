// The outcome of one frame (or one rotation estimate): a status every caller reads, with a reason
// text for people. Callers decide by the status, never by the text or by times.
#pragma once

#include <iosfwd>

namespace visual_gyro {

/// What became of a frame. Only kValid carries a rotation; every other status carries the identity.
enum class FrameStatus {
  kValid,             ///< a trustworthy rotation estimate
  kFirstFrame,        ///< nothing to pair with yet (first frame, after a reset or a camera change)
  kImageRejected,     ///< image unusable (empty, wrong type, size differs from the camera model,
                      ///< smaller than the descriptor patch); skipped
  kStampRejected,     ///< stamp not finite, or not after the previous frame's; skipped
  kTimeStepTooSmall,  ///< less than min_dt after the previous frame; skipped
  kFrontEndFailed,    ///< the front end threw; skipped
  kFrozenImage,       ///< bit-identical to the previous image (frozen camera); no estimate
  /// Nothing to see: grey levels (almost) uniform or no corner found (lens cap, darkness,
  /// overexposure); no estimate, and, as for kFrozenImage, the previous image stays.
  kNoTexture,
  kNotEstimated,      ///< matched only (run_estimator = false), or no estimate was attempted
  kBadBearings,       ///< estimator input unusable: lists of unequal size, non-finite, not unit
  kTooFewMatches,     ///< fewer matches than min_matches
  kDegenerate,        ///< no hypothesis voted: every triple was degenerate
  kFlatHistogram,     ///< the winning bin or cell has fewer than min_votes votes
  kTooFewInliers,     ///< the result explains fewer than min_inlier_ratio of the matches, or its
                      ///< inliers cover fewer than kMinDescriptorAreas descriptor patches
  kImplausibleRate,   ///< the rate exceeds max_rate_dps
  kEstimatorFailed,   ///< the backend failed mid-stream (e.g. a lost GPU)
};

/// snake_case name of a status ("valid", "first_frame", "too_few_matches", ...), as written in
/// messages, CSV files and logs.
const char* frameStatusName(FrameStatus status);

/// Writes frameStatusName(status).
std::ostream& operator<<(std::ostream& out, FrameStatus status);

/// True when the frame was not used at all: the pipeline's state is untouched and the next frame
/// pairs with the last used one (image or stamp rejected, time step below min_dt, front end failed).
bool frameSkipped(FrameStatus status);

}  // namespace visual_gyro
