#include "visual_gyro/frame_status.h"

#include <ostream>

namespace visual_gyro {

const char* frameStatusName(FrameStatus status) {
  switch (status) {
    case FrameStatus::kValid: return "valid";
    case FrameStatus::kFirstFrame: return "first_frame";
    case FrameStatus::kImageRejected: return "image_rejected";
    case FrameStatus::kStampRejected: return "stamp_rejected";
    case FrameStatus::kTimeStepTooSmall: return "time_step_too_small";
    case FrameStatus::kFrontEndFailed: return "front_end_failed";
    case FrameStatus::kFrozenImage: return "frozen_image";
    case FrameStatus::kNoTexture: return "no_texture";
    case FrameStatus::kNotEstimated: return "not_estimated";
    case FrameStatus::kBadBearings: return "bad_bearings";
    case FrameStatus::kTooFewMatches: return "too_few_matches";
    case FrameStatus::kDegenerate: return "degenerate";
    case FrameStatus::kFlatHistogram: return "flat_histogram";
    case FrameStatus::kTooFewInliers: return "too_few_inliers";
    case FrameStatus::kImplausibleRate: return "implausible_rate";
    case FrameStatus::kEstimatorFailed: return "estimator_failed";
  }
  return "unknown";
}

std::ostream& operator<<(std::ostream& out, FrameStatus status) { return out << frameStatusName(status); }

bool frameSkipped(FrameStatus status) {
  return status == FrameStatus::kImageRejected || status == FrameStatus::kStampRejected ||
         status == FrameStatus::kTimeStepTooSmall || status == FrameStatus::kFrontEndFailed;
}

}  // namespace visual_gyro
