// The vote method's second stage: the candidates refined and the refinement that explains the
// matches best chosen (explainsBetter, which also chooses between pure rotation and general
// motion), then the searches for a better basin that the candidates may all have missed: from the
// previous frame's motion, along the rotation/translation valley of a close scene, from other
// translation directions when the winner leaves many matches unexplained or its translation
// loose, and down the truncated cost when it leaves many unexplained. Private to src/core;
// conventions as in rotation_estimator.h (b_prev ~ R b_cur, translation unit in the previous
// camera frame).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "rotation_refinement.h"
#include "vote_candidates.h"

namespace visual_gyro {

/// The refined winner and every refinement that competed with it.
struct RefinementChoice {
  RefinedRotation winner;
  const Candidate* from = nullptr;  ///< the candidate the winner was refined from (in the CandidateVote)
  std::vector<RefinedRotation> contenders;  ///< every refinement, the winner's included
  int runner_up_inliers = -1;               ///< refined inliers of the best loser; -1: none
  /// Adds `r` to the contenders; it replaces the winner when it explains the matches better
  /// (explainsBetter). True when it did.
  bool challenge(const RefinedRotation& r);
};

/// Refines the candidates with a verified count of at least kRefineFraction of the best (at most
/// kMaxRefinedCandidates, the best-verified first; the prior and the identity whatever their
/// count), each with `iterations`, at inlier threshold `threshold` [rad], and chooses. With
/// `all_contenders` false (VotePart::kRefineContenders off) only the best-verified one is refined.
/// `vote` must hold at least one candidate.
RefinementChoice refineCandidates(FrameMatches& matches, const CandidateVote& vote, double threshold, int iterations,
                                  bool all_contenders);

/// The previous frame's motion as one more start: a general-motion refinement from `prior_rotation`
/// and the unit `previous_translation` (both previous camera frame) challenges the winner, unless
/// the winner already moves along that line (within kSameTranslationDeg): it would converge to the
/// winner again. True when it won.
bool refineFromPreviousMotion(FrameMatches& matches, const Eigen::Matrix3d& prior_rotation,
                              const Eigen::Vector3d& previous_translation, double threshold, int iterations,
                              RefinementChoice* choice);

/// The valley of a close scene: a lateral translation t and a rotation about view x t move the
/// image alike to first order. A general-motion winner is re-verified at rotations stepped along
/// that axis (and both axes across `view`, the mean previous bearing, when its refinement kept
/// fewer than kValleyInlierRatio of `best_verified`); the step with the lowest truncated cost,
/// when below the winner's, is refined and challenges it. Returns whether the search ran;
/// *moved: whether its step won.
bool searchValley(FrameMatches& matches, const Eigen::Vector3d& view, int best_verified, double threshold,
                  int iterations, uint64_t seed, RefinementChoice* choice, bool* moved);

/// The translation's standard deviation (RefinedRotation::translation_sigma) [deg] above which a
/// general-motion winner's translation counts as weakly determined and the restarts run whatever
/// the share of matches it explains. Every general-motion frame of the shared sequences lies below
/// it (driving at most 0.05, the drone shaken near the pallet at most 0.15); the close rendered
/// scene straddles it (medians 0.14-0.18, 90th percentiles 0.26-0.30), and so do its basins: a
/// forward-moving winner of 0.47 there was 0.35 deg off, the lateral motion of the frames before
/// it (which the restarts reach) 0.02 deg. It measures the weakness of a lateral translation, the
/// one that trades against the rotation; for a translation towards the view, the first-order
/// covariance of the matches near the epipole understates it. The general-motion frames of a
/// hand-held camera moved by centimetres in a dim room lie far above it (median 0.9-1.4).
constexpr double kWeakTranslationSigmaDeg = 0.2;

/// When a general-motion winner explains fewer than kRestartInlierFraction of the matches, or its
/// translation is weakly determined (kWeakTranslationSigmaDeg), refinements of general motion from
/// the winner's rotation and from the two best-refined contenders elsewhere, each with 13
/// translation directions covering the lines through the camera, challenge it. True when one of
/// them won.
bool restartFromTranslations(FrameMatches& matches, double threshold, int iterations, RefinementChoice* choice);

/// When a general-motion winner explains fewer than kRestartInlierFraction of the matches, it
/// descends on the truncated cost itself (steps of kDescentStepsDeg about the camera axes, each
/// step's translation refitted, the best step taken while it lowers the cost); a refinement from
/// where it ends challenges the winner. True when it won.
bool descendTruncatedCost(FrameMatches& matches, double threshold, int iterations, RefinementChoice* choice);

/// The share of a weakly supported general-motion winner's inliers that a pure rotation must keep
/// to replace it: more than half. Where the translation matters a pure rotation keeps fewer: of the
/// 1 682 noise-limited general-motion pairs of the shared sequences' hard variants in `make score`
/// (estimator seeds 1-3; dim, pairs several frames apart, wrong matches, downscaled), it kept over
/// half on 8, and on 6 of the 72 of the close rendered scene through a rolling shutter.
constexpr double kPureKeepsShare = 0.5;

/// The final choice of model where a general motion rests on weak support, matches so noisy that
/// its fit is noise-limited (its residual sigma times kGateSigmas reaches the threshold, so its
/// rotation is loose along the rotation/translation valley): when the best (least truncated cost)
/// pure rotation, refined from the winner's rotation and from the voted candidates (as many as
/// refineCandidates refines at most), keeps more than kPureKeepsShare of the winner's inliers, the
/// pure rotation becomes the winner; the general motion stays a contender. True when it did.
bool preferPureOnWeakSupport(FrameMatches& matches, const CandidateVote& vote, double threshold, int iterations,
                             RefinementChoice* choice);

/// Once the refinements are chosen (on their rigid fits), where a frame's matches call for the row
/// skew of a rolling shutter: the winner's skewed fit (fitRowSkew, with the rigid fit's inliers)
/// joins the contenders, and takes the winner's place when the stream has confirmed a rolling
/// shutter (`confirmed`). The rigid fit stays among the contenders either way, so that the
/// covariance's contenders' spread covers the rotation the skew moves. True when a skew was fitted.
bool addRowSkew(FrameMatches& matches, double threshold, bool confirmed, RefinementChoice* choice);

/// Where a pure rotation wins, how far an unmodelled translation could move it: the general motion
/// refined from the winner's rotation with each lateral translation (the camera's x and y axes),
/// the lower truncated cost kept. Returns the rotation vector [rad] from the winner to that fit
/// (right perturbation, winner.rotation * exp(offset)); zero for a general-motion winner.
Eigen::Vector3d translationOffset(FrameMatches& matches, const RefinedRotation& winner, double threshold,
                                  int iterations);

}  // namespace visual_gyro
