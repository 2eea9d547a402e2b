// The vote method's covariance model (vote_covariance.h).
#include "vote_covariance.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace visual_gyro {

namespace {

// The scale of sigma^2 (J^T W J)^-1 and the jackknives it is widened to cover (see voteCovariance).
struct ScaledCovariance {
  double inflation = 1.0;
  JackknifeSpread jack, refit;
};

// Refined positions: the mean ratio of the jackknife's covariance to the statistical one. The
// jackknife's steps keep the inliers fixed; when many matches lie just outside the gate, which of
// them it keeps moves the solution as much as the inliers' own errors do, and the refits without
// each group, choosing their inliers anew, show by how much.
ScaledCovariance scaleFromJackknives(FrameMatches& matches, FrameMatches* refit_matches, const RefinedRotation& winner,
                                     const CovarianceInput& input, VoteDiagnostics* diagnostics) {
  ScaledCovariance out;
  out.jack = jackknifeSpread(matches, winner, input.threshold);
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(winner.covariance);
  if (out.jack.groups > 0 && lu.isInvertible())
    out.inflation = std::max(1.0, (lu.inverse() * out.jack.covariance).trace() / 3.0);
  diagnostics->near_miss_share = out.jack.near_miss_share;
  if (input.refit_jackknife && out.jack.near_miss_share >= kRefitNearMissShare && lu.isInvertible()) {
    out.refit = refitJackknifeSpread(matches, refit_matches, winner, input.threshold, input.iterations);
    diagnostics->refit_jackknife = out.refit.groups > 0;
    if (out.refit.groups > 0) out.inflation = std::max(out.inflation, (lu.inverse() * out.refit.covariance).trace() / 3.0);
  }
  return out;
}

// How indistinguishable a contender's inlier count is from the winner's: the count's standard
// deviation is about sqrt(count) (binomial, most matches inliers), so a contender z such deviations
// behind weighs exp(-z^2 / 2).
double countWeight(const RefinedRotation& winner, const RefinedRotation& contender) {
  const double z = (winner.inliers - contender.inliers) / std::sqrt(std::max(1, winner.inliers));
  return std::exp(-0.5 * z * z);
}

// The weighted second moment about the winner is that of the mixture of the winner and its
// contenders (a close scene's rotation/translation valley: two rotations a degree apart, each with
// its translation, that differ by fewer inliers than the count's own noise).
Eigen::Matrix3d contenderSpread(const RefinedRotation& winner, const std::vector<RefinedRotation>& contenders) {
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  double weights = 1.0;
  for (const RefinedRotation& c : contenders) {
    const Eigen::Vector3d d = so3Log(winner.rotation.transpose() * c.rotation);
    if (d.norm() < 1e-9) continue;  // converged to the winner itself
    const double w = countWeight(winner, c);
    spread += w * d * d.transpose();
    weights += w;
  }
  return spread / weights;
}

}  // namespace

VoteCovariance voteCovariance(FrameMatches& matches, FrameMatches* refit_matches, const RefinedRotation& winner,
                              const std::vector<RefinedRotation>& contenders, const CovarianceInput& input,
                              VoteDiagnostics* diagnostics) {
  ScaledCovariance scaled;
  scaled.inflation = std::max(1.0, winner.inliers / kIntegerPositionsEffectiveMatches);
  if (input.refined_positions) scaled = scaleFromJackknives(matches, refit_matches, winner, input, diagnostics);
  diagnostics->effective_matches = winner.inliers / scaled.inflation;
  Eigen::Matrix3d covariance = winner.covariance * scaled.inflation;
  // The scale is a mean over directions: where a jackknife spreads further than the scaled
  // covariance along one direction (the rotation/translation valley's, near structure), the scale
  // alone leaves the covariance too thin there, and on pairs several frames apart the errors fell
  // along such directions. So the covariance also covers each jackknife's spread in every
  // direction; the scale stays as its floor, the steadier estimate of the two.
  if (scaled.jack.groups > 0) covariance = coverInEveryDirection(covariance, scaled.jack.covariance);
  if (scaled.refit.groups > 0) covariance = coverInEveryDirection(covariance, scaled.refit.covariance);
  if (input.contender_spread) covariance += contenderSpread(winner, contenders);
  covariance += translationSpread(input.translation_offset, input.view);
  const double floor = rotationCovarianceFloor(input.refined_positions);
  covariance.diagonal().array() += floor * floor;
  for (int k = 0; k < 3; ++k) covariance(k, k) = std::max(covariance(k, k), input.min_variance);
  // Each term is symmetric, but a weighted outer product (w d) d^T is so only up to rounding; the
  // published covariance is symmetric exactly (a fusion filter may test it).
  return {0.5 * (covariance + covariance.transpose()), scaled.inflation};
}

// Where the matches leave the rotation weakly determined (few, noisy matches; a close scene's
// valley), refinements of one model end in several basins whose costs differ by less than the
// matches can tell apart once their shared errors are counted, and on either side of the truth:
// dim, noisy footage of a drive has lateral translations a degree off both ways. Their likelihood
// weighted mean is the better estimate there, while a basin clearly beaten by its count or its
// cost weighs nothing. Only the winner's own model: a pure rotation's 2-D residuals, or a row
// skew's three more parameters, give costs that do not compare.
Eigen::Matrix3d mixtureMean(const RefinedRotation& winner, const std::vector<RefinedRotation>& contenders,
                            double scale) {
  const double variance = winner.residual_sigma * winner.residual_sigma * scale;
  if (!(variance > 0.0) || !std::isfinite(variance)) return winner.rotation;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weights = 1.0;
  for (const RefinedRotation& c : contenders) {
    if (c.pure_rotation != winner.pure_rotation || c.row_skew.isZero() != winner.row_skew.isZero()) continue;
    const Eigen::Vector3d d = so3Log(winner.rotation.transpose() * c.rotation);
    if (d.norm() < 1e-9) continue;  // converged to the winner itself
    const double cost = std::max(0.0, c.truncated_cost - winner.truncated_cost) / variance;
    const double w = countWeight(winner, c) * std::exp(-0.5 * cost);
    sum += w * d;
    weights += w;
  }
  return winner.rotation * so3Exp(sum / weights);
}

Eigen::Matrix3d translationSpread(const Eigen::Vector3d& offset, const Eigen::Vector3d& view) {
  return 0.5 * offset.squaredNorm() * (Eigen::Matrix3d::Identity() - view * view.transpose());
}

Eigen::Matrix3d coverInEveryDirection(const Eigen::Matrix3d& covariance, const Eigen::Matrix3d& spread) {
  if (!spread.allFinite()) return covariance;
  const Eigen::LLT<Eigen::Matrix3d> llt(covariance);
  if (llt.info() != Eigen::Success) return covariance;
  const Eigen::Matrix3d l = llt.matrixL();
  const Eigen::Matrix3d l_inverse = l.inverse();
  // In the metric of `covariance` it is the identity, so the larger variance along each
  // eigen-direction of the whitened spread is max(eigenvalue, 1).
  const Eigen::Matrix3d whitened = l_inverse * (0.5 * (spread + spread.transpose())) * l_inverse.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(whitened);
  if (eigen.info() != Eigen::Success) return covariance;
  const Eigen::Vector3d larger = eigen.eigenvalues().cwiseMax(1.0);
  const Eigen::Matrix3d covered = l * eigen.eigenvectors() * larger.asDiagonal() * eigen.eigenvectors().transpose() *
                                  l.transpose();
  return 0.5 * (covered + covered.transpose());
}

}  // namespace visual_gyro
