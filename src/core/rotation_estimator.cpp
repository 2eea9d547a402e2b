// Rotation estimator: the paper's yaw voting and the 3-D voting + verification + refinement method.
#include "visual_gyro/rotation_estimator.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>
#include <utility>

#include <Eigen/Dense>

#include "hypothesis_voter.h"
#include "candidate_refinement.h"
#include "rotation_refinement.h"
#include "vote_candidates.h"
#include "vote_covariance.h"

#ifdef VISUAL_GYRO_WITH_CUDA
#include "cuda_voter.h"
#endif

namespace visual_gyro {

namespace {

constexpr double kDeg = kDegToRad;

double elapsedMs(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

void requireValidSettings(const EstimatorSettings& settings) {
  const std::string problem = validateSettings(settings);
  if (!problem.empty()) throw std::invalid_argument("invalid estimator settings: " + problem);
}

RotationResult invalidResult(FrameStatus status, const std::string& why) {
  RotationResult result;
  result.invalidate(status, why);
  return result;
}

// Rejects what would otherwise become silent garbage downstream: unequal lists, NaNs, non-unit
// vectors (a caller passing pixels instead of bearings is the likely mistake).
std::string checkBearings(const std::vector<Eigen::Vector3d>& previous,
                          const std::vector<Eigen::Vector3d>& current, int min_matches, FrameStatus* status) {
  *status = FrameStatus::kBadBearings;
  if (previous.size() != current.size()) {
    std::ostringstream s;
    s << "bearing lists differ in size (" << previous.size() << " previous, " << current.size()
      << " current)";
    return s.str();
  }
  if (static_cast<int>(previous.size()) < std::max(3, min_matches)) {
    *status = FrameStatus::kTooFewMatches;
    std::ostringstream s;
    s << "too few matches: " << previous.size() << " (need " << std::max(3, min_matches) << ")";
    return s.str();
  }
  for (size_t i = 0; i < previous.size(); ++i) {
    for (const Eigen::Vector3d* b : {&previous[i], &current[i]}) {
      if (!b->allFinite()) return "bearing " + std::to_string(i) + " is not finite";
      if (std::abs(b->norm() - 1.0) > 1e-3)
        return "bearing " + std::to_string(i) + " is not a unit vector (norm " +
               std::to_string(b->norm()) + ")";
    }
  }
  return "";
}

void toFloat(const std::vector<Eigen::Vector3d>& v, std::vector<hyp::Vec3f>* out) {
  out->resize(v.size());
  for (size_t i = 0; i < v.size(); ++i)
    (*out)[i] = hyp::make3(static_cast<float>(v[i].x()), static_cast<float>(v[i].y()),
                           static_cast<float>(v[i].z()));
}

void fillAngles(const Eigen::Matrix3d& R, RotationResult* result) {
  result->rotation = R;
  result->quaternion = Eigen::Quaterniond(R).normalized();
  result->rotation_vector = so3Log(R);
  const Eigen::Vector3d ypr = yawPitchRollFromRotation(R);
  result->yaw = ypr[0];
  result->pitch = ypr[1];
  result->roll = ypr[2];
}

}  // namespace

// ---------------------------------------------------------------------------------------------

/// One frame's bearings as the voter (float) and the verification and refinement (structure of
/// arrays) read them, kept between frames so that a frame allocates nothing once they have grown.
struct VoteWorkspace {
  std::vector<hyp::Vec3f> prev, cur;
  FrameMatches matches;
  FrameMatches refit_matches;  ///< the refit jackknife's matches without one group
};

// ---------------------------------------------------------------------------------------------

void RotationResult::invalidate(FrameStatus why, const std::string& details) {
  status = why == FrameStatus::kValid ? FrameStatus::kEstimatorFailed : why;
  reason = details;
  rotation.setIdentity();
  quaternion.setIdentity();
  rotation_vector.setZero();
  translation.setZero();
  yaw = pitch = roll = 0.0;
  covariance.setIdentity();
}

// votePartName's names, indexed by VotePart.
constexpr std::array<const char*, static_cast<size_t>(VotePart::kCount)> kVotePartNames = {
    "wide_vote", "prior_candidate", "identity_candidate", "refine_contenders", "previous_motion",
    "valley", "restarts", "descent", "refit_jackknife", "contender_spread", "row_skew", "translation_spread",
    "contender_mean", "weak_support"};

const char* votePartName(VotePart part) {
  return part < VotePart::kCount ? kVotePartNames[static_cast<size_t>(part)] : "";
}

// The value among `values` whose name (nameOf) is `name`.
template <typename Enum, typename Values, typename NameOf>
bool parseNamed(const std::string& name, const Values& values, NameOf nameOf, Enum* out) {
  for (const Enum value : values) {
    if (name == nameOf(value)) {
      *out = value;
      return true;
    }
  }
  return false;
}

bool parseVotePart(const std::string& name, VotePart* part) {
  std::array<VotePart, kVotePartNames.size()> parts;
  for (size_t k = 0; k < parts.size(); ++k) parts[k] = static_cast<VotePart>(k);
  return parseNamed(name, parts, votePartName, part);
}

const char* methodName(EstimationMethod method) {
  return method == EstimationMethod::kPaper ? "paper" : "vote";
}

const char* backendChoiceName(BackendChoice backend) {
  switch (backend) {
    case BackendChoice::kCpu: return "cpu";
    case BackendChoice::kCuda: return "cuda";
    case BackendChoice::kAuto: break;
  }
  return "auto";
}

bool parseMethod(const std::string& name, EstimationMethod* method) {
  return parseNamed(name, std::array{EstimationMethod::kVote, EstimationMethod::kPaper}, methodName, method);
}

bool parseBackendChoice(const std::string& name, BackendChoice* backend) {
  return parseNamed(name, std::array{BackendChoice::kAuto, BackendChoice::kCpu, BackendChoice::kCuda},
                    backendChoiceName, backend);
}

const std::vector<SettingField<EstimatorSettings>>& estimatorSettingFields() {
  using S = EstimatorSettings;
  static const std::vector<SettingField<S>> fields = {
      enumField<S, EstimationMethod>("method", &S::method,
                                     {{"vote", EstimationMethod::kVote}, {"paper", EstimationMethod::kPaper}},
                                     "vote: 3-D rotation voting, verification and refinement; paper: faithful yaw voting"),
      enumField<S, BackendChoice>("backend", &S::backend,
                                  {{"auto", BackendChoice::kAuto}, {"cpu", BackendChoice::kCpu}, {"cuda", BackendChoice::kCuda}},
                                  "`auto`: CUDA when a device works, else the CPU (one warning when CUDA is compiled in); "
                                  "`cuda`: the CPU with one warning when no device works; read once at start by the node"),
      intField<S>("hypotheses", &S::hypotheses, 1, 10000000, "", "triples drawn per frame"),
      intField<S>("seed", &S::seed, 0, 2147483647, "", "Philox seed; frame f draws with seed + f"),
      doubleField<S>("min_separation_deg", &S::min_separation_deg, 0.0, 10.0, "deg",
                     "a triple with two bearings closer than this is degenerate"),
      doubleField<S>("min_triangle_area_deg2", &S::min_triangle_area_deg2, 0.0, 100.0, "deg^2",
                     "a triple with a smaller triangle is degenerate"),
      boolField<S>("centroid_subtraction", &S::centroid_subtraction, "paper: subtract centroids before Arun's SVD"),
      doubleField<S>("yaw_bin_deg", &S::yaw_bin_deg, 0.001, 10.0, "deg", "paper: yaw histogram bin width"),
      doubleField<S>("yaw_window_deg", &S::yaw_window_deg, 0.1, 179.0, "deg",
                     "paper: the yaw histogram covers [-window, +window)"),
      doubleField<S>("rotation_bin_deg", &S::rotation_bin_deg, 0.01, 10.0, "deg",
                     "vote: cell width of the rotation-vector histogram"),
      doubleField<S>("rotation_window_deg", &S::rotation_window_deg, 0.1, 89.0, "deg",
                     "vote: half window around the prior (at most 128 cells an axis: a finer bin is widened)"),
      doubleField<S>("wide_window_deg", &S::wide_window_deg, 0.1, 89.0, "deg",
                     "vote: half window of the prior-free vote"),
      doubleField<S>("max_angle_change_deg", &S::max_angle_change_deg, 0.0, 10.0, "deg",
                     "vote: triples whose pairwise angles change more are voted out (0 = off)"),
      intField<S>("candidates", &S::candidates, 1, 50, "", "vote: fullest cells verified against all matches"),
      doubleField<S>("inlier_threshold_deg", &S::inlier_threshold_deg, 0.001, 10.0, "deg", "vote: residual of an inlier (about 1.2 px at KITTI's focal length)"),
      boolField<S>("use_prior", &S::use_prior, "vote: centre the window on the previous rotation"),
      intField<S>("refine_iterations", &S::refine_iterations, 0, 100, "", "vote: Gauss-Newton refinement iterations"),
      intField<S>("min_matches", &S::min_matches, 3, 10000, "", "fewer matches give an invalid estimate"),
      intField<S>("min_votes", &S::min_votes, 1, 100000, "", "a winning cell with fewer votes gives an invalid estimate"),
      doubleField<S>("min_inlier_ratio", &S::min_inlier_ratio, 0.0, 1.0, "",
                     "vote: a smaller fraction of inliers gives an invalid estimate"),
      doubleField<S>("min_covariance_rad2", &S::min_covariance_rad2, 1e-12, 1.0, "rad^2",
                     "floor of each rotation covariance diagonal entry (the Imu floor is this / dt^2)"),
  };
  return fields;
}

std::string validateSettings(const EstimatorSettings& s) { return checkRanges(s, estimatorSettingFields()); }

// ---------------------------------------------------------------------------------------------

RotationPrior PriorTracker::priorFor(double dt) const {
  RotationPrior prior = last_;
  if (prior.valid && last_dt_ > 0.0 && dt > 0.0) prior.rotation_vector *= dt / last_dt_;
  return prior;
}

void PriorTracker::update(const RotationResult& result, double dt) {
  last_.valid = result.valid();
  last_.rotation_vector = result.valid() ? result.rotation_vector : Eigen::Vector3d::Zero();
  last_.translation = result.valid() ? result.translation : Eigen::Vector3d::Zero();
  last_dt_ = dt;
}

// ---------------------------------------------------------------------------------------------

RotationEstimator::RotationEstimator(const EstimatorSettings& settings,
                                     std::unique_ptr<HypothesisVoter> voter)
    : settings_(settings),
      voter_(std::move(voter)),
      votes_(std::make_unique<VoteResult>()),
      workspace_(std::make_unique<VoteWorkspace>()) {
  requireValidSettings(settings_);
  if (!voter_) throw std::invalid_argument("RotationEstimator needs a voter");
  backend_ = backendNamed(voter_->name());
}

RotationEstimator::~RotationEstimator() = default;

void RotationEstimator::setSettings(const EstimatorSettings& settings) {
  requireValidSettings(settings);
  settings_ = settings;
}

RotationResult RotationEstimator::estimateSameFrame(const std::vector<Eigen::Vector3d>& previous,
                                                    const std::vector<Eigen::Vector3d>& current,
                                                    const RotationPrior& prior) {
  if (frame_count_ > 0) --frame_count_;
  return estimate(previous, current, prior);
}

RotationResult RotationEstimator::estimate(const std::vector<Eigen::Vector3d>& previous,
                                           const std::vector<Eigen::Vector3d>& current,
                                           const RotationPrior& prior) {
  const auto start = std::chrono::steady_clock::now();
  vote_ms_ = vote_device_ms_ = 0.0;
  RotationResult result;
  FrameStatus input_status = FrameStatus::kValid;
  const std::string problem = checkBearings(previous, current, settings_.min_matches, &input_status);
  if (!problem.empty()) {
    result = invalidResult(input_status, problem);
    result.matches_used = static_cast<int>(std::min(previous.size(), current.size()));
  } else {
    try {
      result = settings_.method == EstimationMethod::kPaper ? estimatePaper(previous, current)
                                           : estimateVote(previous, current, prior);
    } catch (const std::exception& e) {
      // A backend failure mid-stream (e.g. a lost GPU) must not take the caller down.
      result = invalidResult(FrameStatus::kEstimatorFailed, std::string("estimator failed: ") + e.what());
    }
    result.matches_used = static_cast<int>(previous.size());
  }
  ++frame_count_;
  result.backend = backend_;
  result.times.estimate = elapsedMs(start);
  result.times.vote = vote_ms_;
  result.times.vote_device = vote_device_ms_;
  result.times.refine = std::max(0.0, result.times.estimate - vote_ms_);
  return result;
}

void RotationEstimator::castVotes(const VoteRequest& request, VoteResult* votes) {
  const auto start = std::chrono::steady_clock::now();
  voter_->vote(request, votes);
  vote_ms_ += elapsedMs(start);
  vote_device_ms_ += votes->device_ms;
}

// The faithful reproduction: centroid-subtracted (by default) Arun rotations of random triples,
// yaw into a histogram, the fullest bin wins and is read at its centre.
RotationResult RotationEstimator::estimatePaper(const std::vector<Eigen::Vector3d>& previous,
                                                const std::vector<Eigen::Vector3d>& current) {
  std::vector<hyp::Vec3f>& prev = workspace_->prev;
  std::vector<hyp::Vec3f>& cur = workspace_->cur;
  toFloat(previous, &prev);
  toFloat(current, &cur);
  VoteRequest request;
  request.prev = prev.data();
  request.cur = cur.data();
  request.matches = static_cast<uint32_t>(prev.size());
  request.hypotheses = static_cast<uint32_t>(settings_.hypotheses);
  request.seed = settings_.seed + frame_count_;
  request.triple = tripleOptions(settings_, settings_.centroid_subtraction, 0.0);
  request.grid.kind = hyp::kVoteYaw;
  request.grid.centre[0] = request.grid.centre[1] = request.grid.centre[2] = 0.f;
  request.grid.bin_width = static_cast<float>(settings_.yaw_bin_deg * kDeg);
  request.grid.bins = binsFor(settings_.yaw_window_deg, settings_.yaw_bin_deg);
  VoteResult& votes = *votes_;
  castVotes(request, &votes);

  RotationResult result;
  result.hypotheses_drawn = settings_.hypotheses;
  result.hypotheses_accepted = static_cast<int>(votes.accepted);
  if (votes.winner < 0) return invalidResult(FrameStatus::kDegenerate, "no hypothesis voted (all triples degenerate)");
  const int count = votes.histogram[votes.winner];
  result.winning_votes = count;
  const double yaw = hyp::binCentre(votes.winner, 0.f, request.grid);
  // Pitch and roll are not voted on; the winning bin's hypotheses' mean stands in for them.
  const double pitch = votes.cell_sums[3 * votes.winner + 1] / count;
  const double roll = votes.cell_sums[3 * votes.winner + 2] / count;
  const Eigen::Matrix3d R = rotationFromYawPitchRoll(yaw, pitch, roll);
  fillAngles(R, &result);
  // The paper gives no uncertainty; a uniform distribution over the winning bin is the honest floor
  // for yaw, and pitch/roll are as uncertain as the window.
  const double bin = settings_.yaw_bin_deg * kDeg;
  const double window = settings_.yaw_window_deg * kDeg;
  result.covariance = Eigen::Vector3d(window * window / 3.0, bin * bin / 12.0, window * window / 3.0)
                          .asDiagonal();
  result.covariance.diagonal() =
      result.covariance.diagonal().cwiseMax(settings_.min_covariance_rad2);
  result.status = FrameStatus::kValid;
  if (count < settings_.min_votes) {
    result.invalidate(FrameStatus::kFlatHistogram, "winning bin has " + std::to_string(count) +
                                                       " votes (need " + std::to_string(settings_.min_votes) + ")");
  }
  return result;
}

// ---------------------------------------------------------------------------------------------
// The vote method, as stages: candidates from 3-D voting of rotation-only triples, each verified
// against every match (vote_candidates.h); their refinement, the choice between them and between
// pure rotation and general motion, and the searches for a better basin (candidate_refinement.h);
// the covariance (vote_covariance.h); the judgement of whether the matches support the result.

namespace {

// The mean viewing direction of the bearings (unit).
Eigen::Vector3d meanBearing(const std::vector<Eigen::Vector3d>& bearings) {
  Eigen::Vector3d view = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& b : bearings) view += b;
  return view.normalized();
}

// The prior rotation vector when the narrow vote may centre on it (finite, under 60 deg), else null.
const Eigen::Vector3d* usablePrior(const EstimatorSettings& settings, const RotationPrior& prior) {
  const bool usable = settings.use_prior && prior.valid && prior.rotation_vector.allFinite() &&
                      prior.rotation_vector.norm() < 60.0 * kDeg;
  return usable ? &prior.rotation_vector : nullptr;
}

// What the voting stage reads of this frame.
CandidateVoteInput candidateInput(const RotationEstimator& estimator, VoteWorkspace& w, uint64_t seed,
                                  const Eigen::Vector3d* prior, double needed) {
  return {&estimator.settings(), &w.prev, &w.cur, &w.matches, seed, prior, needed,
          estimator.partEnabled(VotePart::kWideVote), estimator.partEnabled(VotePart::kPriorCandidate),
          estimator.partEnabled(VotePart::kIdentityCandidate)};
}

// What the covariance model reads of this frame besides the winner.
CovarianceInput covarianceInput(const RotationEstimator& estimator, FrameMatches& matches, const RefinedRotation& winner,
                                double threshold, bool refined_positions, const Eigen::Vector3d& view) {
  const int iterations = estimator.settings().refine_iterations;
  const Eigen::Vector3d translation_offset = estimator.partEnabled(VotePart::kTranslationSpread)
                                                 ? translationOffset(matches, winner, threshold, iterations)
                                                 : Eigen::Vector3d::Zero();
  return {threshold, iterations, refined_positions, estimator.partEnabled(VotePart::kRefitJackknife),
          estimator.partEnabled(VotePart::kContenderSpread), translation_offset, view,
          estimator.settings().min_covariance_rad2};
}

// The result's counts and diagnostics from the vote and the chosen refinement.
void fillVoteResult(const CandidateVote& vote, const RefinementChoice& choice, const Eigen::Vector3d* prior,
                    RotationResult* result) {
  result->inliers = choice.winner.inliers;
  result->pure_rotation = choice.winner.pure_rotation;
  result->hypotheses_drawn = vote.hypotheses_drawn;
  result->hypotheses_accepted = vote.hypotheses_accepted;
  result->winning_votes = vote.winning_votes;
  VoteDiagnostics* diagnostics = &result->diagnostics;
  diagnostics->prior_used = prior != nullptr;
  diagnostics->wide_vote = vote.wide_vote;
  diagnostics->candidates_verified = static_cast<int>(vote.candidates.size());
  diagnostics->winner_source = diagnostics->weak_support_pure     ? "weak_support"
                               : diagnostics->descent_won         ? "descent"
                               : diagnostics->restart_won         ? "restart"
                               : diagnostics->previous_motion_won ? "previous_motion"
                                                                  : candidateSourceName(choice.from->source);
  diagnostics->runner_up_inliers = choice.runner_up_inliers;
  diagnostics->rotation_inliers = choice.from->verified.rotation_inliers;
  diagnostics->epipolar_inliers = choice.from->verified.epipolar_inliers;
  diagnostics->residual_sigma = choice.winner.residual_sigma;
  diagnostics->row_skew = choice.winner.row_skew;
  if (prior != nullptr) diagnostics->prior_offset = rotationAngleBetween(so3Exp(*prior), choice.winner.rotation);
}

// Invalidates a result the matches do not support: a flat histogram, too few inliers, or inliers
// concentrated within a few descriptor patches (descriptor_areas NaN: no footprint, no check).
void judgeSupport(int min_votes, double needed, int matches, RotationResult* result) {
  const VoteDiagnostics& d = result->diagnostics;
  if (result->winning_votes < min_votes) {
    result->invalidate(FrameStatus::kFlatHistogram, "winning cell has " + std::to_string(result->winning_votes) +
                                                        " votes (need " + std::to_string(min_votes) + ")");
  } else if (result->inliers < needed) {
    result->invalidate(FrameStatus::kTooFewInliers,
                       std::to_string(result->inliers) + " inliers of " + std::to_string(matches) + " matches");
  } else if (d.descriptor_areas < kMinDescriptorAreas) {
    std::ostringstream why;
    why << "inliers too concentrated: their hull covers " << std::fixed << std::setprecision(1) << d.descriptor_areas
        << " descriptor patches (need " << std::defaultfloat << kMinDescriptorAreas
        << "; the image may be too small for the descriptor)";
    result->invalidate(FrameStatus::kTooFewInliers, why.str());
  }
}

}  // namespace

RotationResult RotationEstimator::estimateVote(const std::vector<Eigen::Vector3d>& previous,
                                               const std::vector<Eigen::Vector3d>& current,
                                               const RotationPrior& prior) {
  VoteWorkspace& w = *workspace_;
  toFloat(previous, &w.prev);
  toFloat(current, &w.cur);
  w.matches.assign(previous, current);
  const int n = static_cast<int>(previous.size());
  const double threshold = settings_.inlier_threshold_deg * kDeg;
  const int iterations = settings_.refine_iterations;
  const double needed = std::max<double>(settings_.min_matches, settings_.min_inlier_ratio * n);
  const uint64_t seed = settings_.seed + frame_count_;
  const Eigen::Vector3d* prior_rotation = usablePrior(settings_, prior);
  const CandidateVote vote = voteCandidates(candidateInput(*this, w, seed, prior_rotation, needed),
                                            [this](const VoteRequest& r, VoteResult* v) { castVotes(r, v); },
                                            votes_.get());
  if (vote.best_verified == 0) return invalidResult(FrameStatus::kDegenerate, "no candidate rotation (all triples degenerate)");

  RotationResult result;
  VoteDiagnostics& diagnostics = result.diagnostics;
  const Eigen::Vector3d view = meanBearing(previous);
  RefinementChoice choice =
      refineCandidates(w.matches, vote, threshold, iterations, partEnabled(VotePart::kRefineContenders));
  if (partEnabled(VotePart::kPreviousMotion) && prior_rotation != nullptr && prior.translation.allFinite() &&
      prior.translation.norm() > 0.5)
    diagnostics.previous_motion_won = refineFromPreviousMotion(
        w.matches, so3Exp(*prior_rotation), prior.translation.normalized(), threshold, iterations, &choice);
  if (partEnabled(VotePart::kValley))
    diagnostics.valley_searched = searchValley(w.matches, view, vote.best_verified, threshold, iterations, seed,
                                               &choice, &diagnostics.valley_moved);
  if (partEnabled(VotePart::kRestarts))
    diagnostics.restart_won = restartFromTranslations(w.matches, threshold, iterations, &choice);
  if (partEnabled(VotePart::kDescent))
    diagnostics.descent_won = descendTruncatedCost(w.matches, threshold, iterations, &choice);
  if (partEnabled(VotePart::kWeakSupport))
    diagnostics.weak_support_pure = preferPureOnWeakSupport(w.matches, vote, threshold, iterations, &choice);
  if (partEnabled(VotePart::kRowSkew)) {
    // Once the stream has shown a rolling shutter every frame takes the skew; before (and on a
    // global shutter's odd frame) the frame's own call for one is not followed, but its rotation is
    // as likely as the rigid one.
    const double significance = rowSkewSignificance(w.matches, choice.winner, threshold);
    const bool confirmed = rollingShutterSeen(significance);
    if (confirmed || significance > kRowSkewSignificance) addRowSkew(w.matches, threshold, confirmed, &choice);
  }

  const RefinedRotation& winner = choice.winner;
  result.translation = winner.pure_rotation ? Eigen::Vector3d::Zero() : winner.translation;
  const VoteCovariance uncertainty =
      voteCovariance(w.matches, &w.refit_matches, winner, choice.contenders,
                     covarianceInput(*this, w.matches, winner, threshold, refined_positions_, view), &diagnostics);
  result.covariance = uncertainty.covariance;
  fillAngles(partEnabled(VotePart::kContenderMean) ? mixtureMean(winner, choice.contenders, uncertainty.scale)
                                                   : winner.rotation,
             &result);
  fillVoteResult(vote, choice, prior_rotation, &result);
  if (match_footprint_ > 0.0)
    diagnostics.descriptor_areas = inlierHullArea(w.matches, winner, threshold) / (match_footprint_ * match_footprint_);
  result.status = FrameStatus::kValid;
  judgeSupport(settings_.min_votes, needed, n, &result);
  return result;
}

// ---------------------------------------------------------------------------------------------

// A rolling shutter belongs to the camera: once the median significance over the last
// kRowSkewWindowFrames frames calls for a skew, every frame takes one, whether its own matches
// reject a global shutter or not. At a steady rate the step from the rigid fit is small and the
// frame alone may pass no test, yet the fit still moves the rotation to the principal point's row
// (drone_near through a 28 ms read-out: frames 0.6 deg off came within 0.06 deg). On hard
// footage through a global shutter one or two frames in thirty call for a skew, which then only
// absorbs other errors (a frame of euroc_mh01_shake at stride 3: 0.06 -> 0.32 deg); a median over
// five frames needs three such frames, so a stream is judged from its fifth frame on rather than
// after a full window, whose first frames a rolling shutter would otherwise leave unmodelled.
bool RotationEstimator::rollingShutterSeen(double significance) {
  if (!std::isfinite(significance)) return false;
  // A frame estimated again (estimateSameFrame) replaces its own entry: the window counts frames.
  if (!skew_significance_.empty() && skew_significance_frame_ == frame_count_) skew_significance_.back() = significance;
  else skew_significance_.push_back(significance);
  skew_significance_frame_ = frame_count_;
  if (skew_significance_.size() > kRowSkewWindowFrames) skew_significance_.erase(skew_significance_.begin());
  const size_t judged = skew_significance_.size();
  if (judged < kRowSkewMinFrames) return false;
  std::array<double, kRowSkewWindowFrames> sorted;
  std::copy(skew_significance_.begin(), skew_significance_.end(), sorted.begin());
  std::nth_element(sorted.begin(), sorted.begin() + judged / 2, sorted.begin() + judged);
  return sorted[judged / 2] > kRowSkewSignificance;
}

bool cudaBackendCompiled() {
#ifdef VISUAL_GYRO_WITH_CUDA
  return true;
#else
  return false;
#endif
}

bool cudaBackendUsable(std::string* why) {
#ifdef VISUAL_GYRO_WITH_CUDA
  return cudaDeviceAvailable(why);
#else
  if (why != nullptr) *why = "this build has no CUDA support";
  return false;
#endif
}

std::unique_ptr<RotationEstimator> createRotationEstimator(const EstimatorSettings& settings,
                                                           const WarningSink& warn) {
  requireValidSettings(settings);
  std::unique_ptr<HypothesisVoter> voter;
  if (settings.backend != BackendChoice::kCpu) {
#ifdef VISUAL_GYRO_WITH_CUDA
    try {
      voter = createCudaVoter();
    } catch (const std::exception& e) {
      if (warn) warn(std::string("CUDA backend unavailable (") + e.what() + "); using the CPU backend");
    }
#else
    if (settings.backend == BackendChoice::kCuda && warn)
      warn("CUDA backend requested but this build has no CUDA support; using the CPU backend");
#endif
  }
  if (!voter) voter = createCpuVoter();
  return std::make_unique<RotationEstimator>(settings, std::move(voter));
}

}  // namespace visual_gyro
