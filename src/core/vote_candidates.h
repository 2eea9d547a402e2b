// The vote method's first stage: rotation-only triples voted into a 3-D histogram of rotation
// vectors, the fullest cells read as candidate rotations, and every candidate verified against
// all the matches. Private to src/core. Conventions as in rotation_estimator.h: b_prev ~ R b_cur.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "hypothesis_voter.h"
#include "rotation_refinement.h"
#include "visual_gyro/rotation_estimator.h"

namespace visual_gyro {

/// Where a candidate rotation came from.
enum class CandidateSource : uint8_t {
  kNarrow,    ///< a cell of the narrow vote around the prior (or zero)
  kWide,      ///< a cell of the prior-free wide vote
  kPrior,     ///< the prior itself
  kIdentity,  ///< no rotation
};
/// "narrow", "wide", "prior" or "identity" (VoteDiagnostics::winner_source).
const char* candidateSourceName(CandidateSource source);

/// A candidate rotation and its verification against every match.
struct Candidate {
  Eigen::Vector3d rotation_vector = Eigen::Vector3d::Zero();  ///< as proposed [rad]
  VerifiedRotation verified;
  CandidateSource source = CandidateSource::kNarrow;
};

/// What the voting stage found.
struct CandidateVote {
  /// Distinct candidates (none within half a cell of another), the most verified inliers first.
  std::vector<Candidate> candidates;
  int best_verified = 0;         ///< the most verified inliers of any candidate
  int winning_votes = 0;         ///< the fullest cell's votes over the votes cast
  int hypotheses_drawn = 0;      ///< over the votes cast
  int hypotheses_accepted = 0;   ///< non-degenerate, over the votes cast
  bool wide_vote = false;        ///< the prior-free wide vote ran
};

/// Runs one vote (the voter, timed by the caller).
using CastVotes = std::function<void(const VoteRequest& request, VoteResult* votes)>;

/// What the voting stage reads.
struct CandidateVoteInput {
  const EstimatorSettings* settings = nullptr;
  const std::vector<hyp::Vec3f>* prev = nullptr;  ///< the previous bearings (float, for the voter)
  const std::vector<hyp::Vec3f>* cur = nullptr;   ///< the current bearings
  FrameMatches* matches = nullptr;                ///< the same matches, for verification
  uint64_t seed = 0;                              ///< the frame's seed
  /// The prior rotation vector [rad] when usable (finite, under 60 deg, use_prior), else null.
  const Eigen::Vector3d* prior = nullptr;
  /// Verified inliers that explain the frame: fewer after the narrow vote run the wide one.
  double needed = 0.0;
  bool wide_vote = true;           ///< VotePart::kWideVote
  bool prior_candidate = true;     ///< VotePart::kPriorCandidate
  bool identity_candidate = true;  ///< VotePart::kIdentityCandidate
};

/// Pass 1 votes in a narrow window around the prior (or zero) with triples whose pairwise angles
/// survive the motion; its fullest cells, the prior and the identity are verified. Pass 2, a wide
/// prior-free window with every non-degenerate triple, runs when pass 1 explains fewer than
/// `needed` matches, the winning cell has fewer than min_votes, or the prior is itself the best
/// candidate (a prior never challenged by the data could carry an error from frame to frame).
CandidateVote voteCandidates(const CandidateVoteInput& input, const CastVotes& cast, VoteResult* votes);

/// The triple options of `settings` (min separation and triangle area), with centroid subtraction
/// when `centroid` and triples whose pairwise angles change by more than `max_change_deg` voted out
/// (0: no such test).
hyp::TripleOptions tripleOptions(const EstimatorSettings& settings, bool centroid, double max_change_deg);

/// Bins of a histogram covering [-window, +window) [deg] with bins of `bin_deg`, at least 1;
/// saturated at INT_MAX (a tiny bin, or NaN, must not become a small histogram).
int binsFor(double window_deg, double bin_deg);

}  // namespace visual_gyro
