// The vote method's covariance model, in one place: the refinement's sigma^2 (J^T W J)^-1 scaled
// by how far the matches' errors are from independent, widened to cover the spatial jackknives'
// spread in every direction, plus the spread of the competing refinements, plus what an unmodelled
// translation moves a pure rotation by, plus a floor; and the estimate that reads its scale, the
// mean over the competing refinements (mixtureMean, doc/method.md step 11). doc/covariance.md
// explains and measures the covariance. Private to src/core; rotation vector covariances [rad^2]
// of the right perturbation R exp(d), as RefinedRotation::covariance.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "rotation_refinement.h"
#include "visual_gyro/rotation_estimator.h"

namespace visual_gyro {

/// What the covariance model reads besides the winner.
struct CovarianceInput {
  double threshold = 0.0;          ///< the inlier threshold [rad]
  int iterations = 0;              ///< refinement iterations of the refit jackknife's refits
  bool refined_positions = false;  ///< RotationEstimator::setRefinedPositions
  bool refit_jackknife = true;     ///< VotePart::kRefitJackknife
  bool contender_spread = true;    ///< VotePart::kContenderSpread
  /// A pure-rotation winner's translationOffset [rad] (zero: none) and the mean previous bearing
  /// (unit), across which that offset is spread.
  Eigen::Vector3d translation_offset = Eigen::Vector3d::Zero();
  Eigen::Vector3d view = Eigen::Vector3d::UnitZ();
  double min_variance = 0.0;       ///< EstimatorSettings::min_covariance_rad2, per diagonal entry
};

/// The covariance of a winner and the scale it took.
struct VoteCovariance {
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();  ///< rotation vector [rad^2]
  /// How many inliers count as one independent match (>= 1): the factor of sigma^2 (J^T W J)^-1,
  /// inliers / VoteDiagnostics::effective_matches.
  double scale = 1.0;
};

/// The covariance of `winner` a fusion filter can weight by. The scale: with refined positions,
/// the mean ratio (in the metric of the statistical covariance) of the spatial jackknife's
/// covariance to the statistical one, at least 1, since matches that share an error (a patch of
/// texture, blur) leave a jackknife group together; with many near misses (at least
/// kRefitNearMissShare per inlier) at least that of the refits without each group, which choose
/// their inliers anew (`refit_matches` holds their matches); with integer positions, inliers /
/// kIntegerPositionsEffectiveMatches (their shared errors are global: no group shows them). Then
/// widened where either jackknife spreads further along some direction (coverInEveryDirection);
/// plus the second moment about the winner of the `contenders` (the refinements that competed),
/// each weighted by how indistinguishable its inlier count is from the winner's; plus
/// translationSpread of the input's translation_offset; plus rotationCovarianceFloor squared on the
/// diagonal, each diagonal entry at least min_variance.
/// *diagnostics receives near_miss_share, refit_jackknife and effective_matches.
VoteCovariance voteCovariance(FrameMatches& matches, FrameMatches* refit_matches, const RefinedRotation& winner,
                              const std::vector<RefinedRotation>& contenders, const CovarianceInput& input,
                              VoteDiagnostics* diagnostics);

/// The mean rotation of the mixture of `winner` and those `contenders` of its own model (pure
/// rotation or general motion, with a row skew or without), each weighted by how likely it is
/// against the winner given two measures of how well it explains the matches: its inlier count
/// (z = (n0 - nj) / sqrt(n0) of the count's own noise, exp(-z^2 / 2), as in the covariance's
/// contenders' spread) and its truncated cost (exp(-(Cj - C0) / (2 sigma^2 scale)), sigma the
/// winner's residual_sigma, `scale` the VoteCovariance's: the cost difference as a chi-square
/// over the matches that count as independent). The mean of the rotation vectors
/// log(R_winner^T R_j) [rad], the winner's zero included with weight 1, is applied to the winner
/// as a right perturbation. The winner's rotation itself when nothing else weighs in.
Eigen::Matrix3d mixtureMean(const RefinedRotation& winner, const std::vector<RefinedRotation>& contenders,
                            double scale);

/// The second moment of a rotation vector [rad] of the length of `offset` in a direction drawn
/// uniformly across `view` (unit): |offset|^2 / 2 (I - view view^T) [rad^2]. A pure rotation's
/// offset to the general fit from it has the bias's size, but not its direction: where the
/// translation is small the matches hardly tell which lateral direction it takes.
Eigen::Matrix3d translationSpread(const Eigen::Vector3d& offset, const Eigen::Vector3d& view);

/// Near misses (JackknifeSpread::near_miss_share) per inlier from which the covariance also takes
/// the refit jackknife's spread.
constexpr double kRefitNearMissShare = 0.1;

/// `covariance` (symmetric positive definite, rad^2) widened to cover `spread` (symmetric positive
/// semi-definite, rad^2) in every direction: with covariance = L L^T
/// and the eigen-decomposition L^-1 spread L^-T = V diag(l) V^T, the result is
/// L V diag(max(l, 1)) V^T L^T. Along each eigen-direction it is the larger of the two variances;
/// the result minus either argument is positive semi-definite. `covariance` is returned unchanged
/// when it is not positive definite or `spread` is not finite.
Eigen::Matrix3d coverInEveryDirection(const Eigen::Matrix3d& covariance, const Eigen::Matrix3d& spread);

}  // namespace visual_gyro
