// Rotation estimator: the paper's yaw voting and the 3-D voting + verification + refinement method.
#include "visual_gyro/rotation_estimator.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <iterator>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <utility>

#include <Eigen/Dense>

#include "hypothesis_voter.h"
#include "rotation_refinement.h"

#ifdef VISUAL_GYRO_WITH_CUDA
#include "cuda_voter.h"
#endif

namespace visual_gyro {

namespace {

constexpr double kDeg = kDegToRad;
// Candidates whose verified count reaches this fraction of the best one are refined before the
// choice (at most kMaxRefinedCandidates of them, the best-verified first).
constexpr double kRefineFraction = 0.6;
constexpr int kMaxRefinedCandidates = 4;
// Valley search: rotation steps [deg] about view x t, and the smallest |view x t| (sine of the
// angle between the translation and the viewing direction) for which it runs.
// Ascending, both signs, without 0 (the winner itself), which the search puts between the signs.
constexpr double kValleySteps[] = {-3.0, -2.0, -1.5, -1.0, -0.5, 0.5, 1.0, 1.5, 2.0, 3.0};
constexpr double kMinValleyLateral = 0.3;
// A general-motion winner whose refinement kept fewer inliers than this fraction of the best
// verified count (refinement lost much of the support the looser verification saw: a wrong basin,
// whose translation says nothing of the true valley) also searches the two axes across the view.
constexpr double kValleyInlierRatio = 0.85;
// Least-squares refits of each valley step's translation: a step is costed at a translation fitted
// to it, as the winner is at its refined one, or the winner's tighter translation alone would make
// it look better than a step in the right basin.
constexpr int kValleyRefits = 3;
// A winner whose translation lies within this angle [deg] of the previous frame's (as lines) skips
// the refinement from the previous motion: it would converge to the winner again.
constexpr double kSameTranslationDeg = 10.0;
// A winner explaining fewer than this fraction of the matches is refined again from several
// translation directions (see estimateVote). Below it lie frames whose every candidate may share
// one wrong basin; above it, frames where the right motion already explains nearly every correct
// match (on the rendered close scene the right motion explains 94-97 % of the matches).
constexpr double kRestartInlierFraction = 0.8;
// Refined contenders whose rotations the restarts also start from, and how far [deg] a start must
// lie from every other start (nearer ones converge alike).
constexpr size_t kRestartContenders = 2;
constexpr double kRestartSeparationDeg = 0.3;
// The descent on the truncated cost after the restarts: its step sizes about the camera axes [deg],
// coarse to fine, and the most moves at each.
constexpr std::array<double, 4> kDescentStepsDeg = {0.2, 0.1, 0.05, 0.025};
constexpr int kDescentMovesPerStep = 20;

// Translation starts of those restarts: unit directions in the camera frame (z forward), one per
// line through the camera, since a translation is only known up to sign: forward, the two image
// axes and their diagonals, and the four half-way between forward and an image axis.
const std::array<Eigen::Vector3d, 9>& restartDirections() {
  static const std::array<Eigen::Vector3d, 9> directions = [] {
    const double h = std::sqrt(0.5);
    return std::array<Eigen::Vector3d, 9>{
        Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 0, 0),  Eigen::Vector3d(0, 1, 0),
        Eigen::Vector3d(h, h, 0), Eigen::Vector3d(h, -h, 0), Eigen::Vector3d(h, 0, h),
        Eigen::Vector3d(-h, 0, h), Eigen::Vector3d(0, h, h), Eigen::Vector3d(0, -h, h)};
  }();
  return directions;
}

// Near misses (JackknifeSpread::near_miss_share) per inlier from which the covariance also takes the refit
// jackknife's spread. Inliers with a Gaussian core and gross outliers leave a few hundredths (a
// core of sigma = gate / 2.2 has 0.03 as much mass between one and three gates as inside one);
// frames of well-lit footage stay below 0.1 (the 90th percentile was 0.09 on euroc_mh01_shake,
// 0.05 on kitti_turn), dim or wide-baseline ones lie above it.
constexpr double kRefitNearMissShare = 0.1;

double elapsedMs(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
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

hyp::TripleOptions tripleOptions(const EstimatorSettings& s, bool centroid, double max_change_deg) {
  hyp::TripleOptions opt;
  opt.centroid_subtraction = centroid ? 1 : 0;
  opt.min_separation = static_cast<float>(2.0 * std::sin(0.5 * s.min_separation_deg * kDeg));
  opt.min_triangle_area = static_cast<float>(s.min_triangle_area_deg2 * kDeg * kDeg);
  opt.max_angle_change = static_cast<float>(max_change_deg * kDeg);
  return opt;
}

// Cells per axis of the vote method's narrow histogram at most (128^3 cells); a finer
// rotation_bin_deg is widened to fit its window.
constexpr int kMaxRotationBins = 128;

int binsFor(double window_deg, double bin_deg) {
  const double bins = std::ceil(2.0 * window_deg / bin_deg - 1e-9);
  // Saturate before converting: a double beyond int's range (a tiny bin) would be undefined
  // behaviour, and NaN must not pass as a small histogram.
  if (!(bins < static_cast<double>(std::numeric_limits<int>::max()))) return std::numeric_limits<int>::max();
  return std::max(1, static_cast<int>(bins));
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

const char* votePartName(VotePart part) {
  switch (part) {
    case VotePart::kWideVote: return "wide_vote";
    case VotePart::kPriorCandidate: return "prior_candidate";
    case VotePart::kIdentityCandidate: return "identity_candidate";
    case VotePart::kRefineContenders: return "refine_contenders";
    case VotePart::kPreviousMotion: return "previous_motion";
    case VotePart::kReverify: return "reverify";
    case VotePart::kValley: return "valley";
    case VotePart::kRestarts: return "restarts";
    case VotePart::kDescent: return "descent";
    case VotePart::kRefitJackknife: return "refit_jackknife";
    case VotePart::kContenderSpread: return "contender_spread";
    case VotePart::kCount: break;
  }
  return "";
}

bool parseVotePart(const std::string& name, VotePart* part) {
  for (int k = 0; k < static_cast<int>(VotePart::kCount); ++k) {
    if (name == votePartName(static_cast<VotePart>(k))) {
      *part = static_cast<VotePart>(k);
      return true;
    }
  }
  return false;
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
  for (const EstimationMethod m : {EstimationMethod::kVote, EstimationMethod::kPaper}) {
    if (name == methodName(m)) {
      *method = m;
      return true;
    }
  }
  return false;
}

bool parseBackendChoice(const std::string& name, BackendChoice* backend) {
  for (const BackendChoice b : {BackendChoice::kAuto, BackendChoice::kCpu, BackendChoice::kCuda}) {
    if (name == backendChoiceName(b)) {
      *backend = b;
      return true;
    }
  }
  return false;
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
                     "vote: half window around the prior (at most 64 cells: a finer bin is widened)"),
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
  const std::string problem = validateSettings(settings_);
  if (!problem.empty()) throw std::invalid_argument("invalid estimator settings: " + problem);
  if (!voter_) throw std::invalid_argument("RotationEstimator needs a voter");
}

RotationEstimator::~RotationEstimator() = default;

void RotationEstimator::setSettings(const EstimatorSettings& settings) {
  const std::string problem = validateSettings(settings);
  if (!problem.empty()) throw std::invalid_argument("invalid estimator settings: " + problem);
  settings_ = settings;
}

std::string RotationEstimator::backendName() const { return voter_->name(); }

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
  result.backend = voter_->name();
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
// The vote method: 3-D voting of rotation-only triples, translation-aware verification of the
// fullest cells, model selection (pure rotation or general motion) and robust refinement.

namespace {

struct Candidate {
  Eigen::Vector3d rotation_vector;
  int votes = 0;
};

// The fullest cells, each read as the vote-weighted mean of its 3x3x3 neighbourhood (which
// absorbs the quantisation of the grid); cells adjacent to an already chosen one are skipped so
// the candidates are distinct modes.
std::vector<Candidate> topCandidates(const VoteResult& votes, const hyp::VoteGrid& grid, int wanted) {
  // The voted cells, found a block at a time: most blocks of a wide histogram hold no vote, and
  // one vectorised test passes over a block.
  std::vector<int> order;
  constexpr int kBlock = 16;
  const int cells = static_cast<int>(votes.histogram.size());
  const int32_t* histogram = votes.histogram.data();
  for (int block = 0; block < cells; block += kBlock) {
    const int end = std::min(cells, block + kBlock);
    int32_t any = 0;
    for (int c = block; c < end; ++c) any |= histogram[c];
    if (any == 0) continue;
    for (int c = block; c < end; ++c)
      if (histogram[c] > 0) order.push_back(c);
  }
  const int keep = std::min<int>(static_cast<int>(order.size()), 8 * wanted);
  std::partial_sort(order.begin(), order.begin() + keep, order.end(), [&](int a, int b) {
    return votes.histogram[a] != votes.histogram[b] ? votes.histogram[a] > votes.histogram[b] : a < b;
  });
  order.resize(keep);
  const int n = grid.bins;
  std::vector<Candidate> out;
  std::vector<Eigen::Vector3i> chosen;
  for (int cell : order) {
    const Eigen::Vector3i ijk(cell / (n * n), (cell / n) % n, cell % n);
    bool near = false;
    for (const auto& c : chosen) near = near || (c - ijk).cwiseAbs().maxCoeff() <= 1;
    if (near) continue;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int count = 0;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const Eigen::Vector3i q = ijk + Eigen::Vector3i(dx, dy, dz);
          if ((q.array() < 0).any() || (q.array() >= n).any()) continue;
          const int qc = (q.x() * n + q.y()) * n + q.z();
          count += votes.histogram[qc];
          sum += Eigen::Vector3d(votes.cell_sums[3 * qc], votes.cell_sums[3 * qc + 1],
                                 votes.cell_sums[3 * qc + 2]);
        }
    Candidate c;
    c.rotation_vector = sum / count;
    c.votes = votes.histogram[cell];
    out.push_back(c);
    chosen.push_back(ijk);
    if (static_cast<int>(out.size()) == wanted) break;
  }
  return out;
}

// A descent on the truncated cost (the choice between refinements) from (rotation, translation):
// steps of kDescentStepsDeg about each camera axis, coarse to fine, each step's translation
// refitted, the best step taken while it lowers the cost. True when it moved.
bool descendTruncatedCost(FrameMatches& matches, double threshold, Eigen::Matrix3d* rotation,
                          Eigen::Vector3d* translation) {
  double cost = fittedTranslationCost(matches, *rotation, translation, threshold, kValleyRefits);
  bool moved = false;
  for (const double step_deg : kDescentStepsDeg) {
    for (int move = 0; move < kDescentMovesPerStep; ++move) {
      double best_cost = cost;
      Eigen::Matrix3d best_rotation = *rotation;
      Eigen::Vector3d best_translation = *translation;
      for (int axis = 0; axis < 3; ++axis) {
        for (const double sign : {1.0, -1.0}) {
          const Eigen::Matrix3d stepped = so3Exp(sign * step_deg * kDeg * Eigen::Vector3d::Unit(axis)) * *rotation;
          Eigen::Vector3d stepped_translation = *translation;
          const double c = fittedTranslationCost(matches, stepped, &stepped_translation, threshold, kValleyRefits);
          if (c < best_cost) {
            best_cost = c;
            best_rotation = stepped;
            best_translation = stepped_translation;
          }
        }
      }
      if (!(best_cost < cost)) break;
      cost = best_cost;
      *rotation = best_rotation;
      *translation = best_translation;
      moved = true;
    }
  }
  return moved;
}

// The covariance a fusion filter can weight by: the refinement's sigma^2 (J^T W J)^-1 scaled up
// by how far the matches' errors are from independent, plus the spread of the competing refined
// candidates that explain the matches about as well as the winner (a close scene's
// rotation/translation valley: two rotations a degree apart, each with its translation, that
// differ by fewer inliers than the count's own noise), plus a floor for the unmodelled errors.
// The scale: with refined positions, the mean ratio (in the metric of the statistical covariance)
// of the spatial jackknife's covariance to the statistical one, at least 1, since matches that
// share an error (a patch of texture, blur) leave a jackknife group together; with integer
// positions, inliers / kIntegerPositionsEffectiveMatches (their shared errors are global: no
// group shows them). With refined positions and many near misses, the scale is at least that of
// the refits without each group (refitJackknifeSpread, on `iterations` each, `refit_matches` their
// matches). The scaled covariance is then widened where either jackknife's spread exceeds it along
// some direction (coverInEveryDirection). The diagnostics get near_miss_share, refit_jackknife and
// effective_matches, the inliers over the scale.
Eigen::Matrix3d honestCovariance(FrameMatches& matches, FrameMatches* refit_matches, const RefinedRotation& winner,
                                 const std::vector<RefinedRotation>& contenders, double threshold,
                                 int iterations, bool refined_positions, bool refit_jackknife,
                                 bool contender_spread, VoteDiagnostics* diagnostics) {
  double inflation = std::max(1.0, winner.inliers / kIntegerPositionsEffectiveMatches);
  JackknifeSpread jack, refit;
  if (refined_positions) {
    inflation = 1.0;
    jack = jackknifeSpread(matches, winner, threshold);
    const Eigen::FullPivLU<Eigen::Matrix3d> lu(winner.covariance);
    if (jack.groups > 0 && lu.isInvertible())
      inflation = std::max(1.0, (lu.inverse() * jack.covariance).trace() / 3.0);
    // The jackknife's steps keep the inliers fixed. When many matches lie just outside the gate,
    // which of them it keeps moves the solution as much as the inliers' own errors do, and the
    // refits without each group, choosing their inliers anew, show by how much.
    diagnostics->near_miss_share = jack.near_miss_share;
    if (refit_jackknife && diagnostics->near_miss_share >= kRefitNearMissShare && lu.isInvertible()) {
      refit = refitJackknifeSpread(matches, refit_matches, winner, threshold, iterations);
      diagnostics->refit_jackknife = refit.groups > 0;
      if (refit.groups > 0) inflation = std::max(inflation, (lu.inverse() * refit.covariance).trace() / 3.0);
    }
  }
  diagnostics->effective_matches = winner.inliers / inflation;
  Eigen::Matrix3d covariance = winner.covariance * inflation;
  // The scale is a mean over directions: where a jackknife spreads further than the scaled
  // covariance along one direction (the rotation/translation valley's, near structure), the scale
  // alone leaves the covariance too thin there, and on pairs several frames apart the errors fell
  // along such directions. So the covariance also covers each jackknife's spread in every
  // direction; the scale stays as its floor, the steadier estimate of the two.
  if (jack.groups > 0) covariance = coverInEveryDirection(covariance, jack.covariance);
  if (refit.groups > 0) covariance = coverInEveryDirection(covariance, refit.covariance);
  // Each contender is weighted by how indistinguishable its inlier count is from the winner's: the
  // count's standard deviation is about sqrt(count) (binomial, most matches inliers), so a
  // contender z such deviations behind weighs exp(-z^2 / 2). The weighted second moment about the
  // winner is that of the mixture of the winner and its contenders.
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  double weights = 1.0;
  for (const RefinedRotation& c : contenders) {
    if (!contender_spread) break;
    const Eigen::Vector3d d = so3Log(winner.rotation.transpose() * c.rotation);
    if (d.norm() < 1e-9) continue;  // converged to the winner itself
    const double z = (winner.inliers - c.inliers) / std::sqrt(std::max(1, winner.inliers));
    const double w = std::exp(-0.5 * z * z);
    spread += w * d * d.transpose();
    weights += w;
  }
  covariance += spread / weights;
  const double floor = rotationCovarianceFloor(refined_positions);
  covariance.diagonal().array() += floor * floor;
  return covariance;
}

}  // namespace

RotationResult RotationEstimator::estimateVote(const std::vector<Eigen::Vector3d>& previous,
                                               const std::vector<Eigen::Vector3d>& current,
                                               const RotationPrior& prior) {
  std::vector<hyp::Vec3f>& prev = workspace_->prev;
  std::vector<hyp::Vec3f>& cur = workspace_->cur;
  toFloat(previous, &prev);
  toFloat(current, &cur);
  FrameMatches& matches = workspace_->matches;
  matches.assign(previous, current);
  const uint64_t seed = settings_.seed + frame_count_;
  const double threshold = settings_.inlier_threshold_deg * kDeg;
  const int n = static_cast<int>(previous.size());

  VoteRequest request;
  request.prev = prev.data();
  request.cur = cur.data();
  request.matches = static_cast<uint32_t>(n);
  request.hypotheses = static_cast<uint32_t>(settings_.hypotheses);
  request.seed = seed;
  request.grid.kind = hyp::kVoteRotationVector;

  const bool prior_usable = settings_.use_prior && prior.valid && prior.rotation_vector.allFinite() &&
                            prior.rotation_vector.norm() < 60.0 * kDeg;
  RotationResult result;
  VoteDiagnostics& diagnostics = result.diagnostics;
  diagnostics.prior_used = prior_usable;
  struct Verified {
    Eigen::Vector3d rotation_vector;  // the candidate as proposed
    VerifiedRotation rotation;
    const char* source;
  };
  std::vector<Verified> verified;
  int best_verified = 0;
  bool best_verified_is_prior = false;
  auto consider = [&](const Eigen::Vector3d& rotation_vector, const char* source) {
    // Candidates within half a cell of one already verified would verify to the same inliers.
    for (const Verified& c : verified)
      if ((c.rotation_vector - rotation_vector).norm() < 0.5 * settings_.rotation_bin_deg * kDeg) return;
    ++diagnostics.candidates_verified;
    // Voted candidates are off by a few tenths of a degree under translation: a looser gate lets
    // them gather the inliers (and the epipole) that refinement then tightens.
    Verified v{rotation_vector, verifyRotation(matches, so3Exp(rotation_vector), 2.0 * threshold, seed),
               source};
    if (v.rotation.inliers > best_verified) {
      best_verified = v.rotation.inliers;
      best_verified_is_prior = std::string(source) == "prior";
    }
    verified.push_back(v);
  };
  const double needed = std::max<double>(settings_.min_matches, settings_.min_inlier_ratio * n);
  // Pass 1: a narrow window around the prior (or zero), voting only with triples whose pairwise
  // angles survive the motion (far points: rotation-only triples are unbiased there).
  // Pass 2, a wide window without the prior and with every non-degenerate triple, runs when pass 1
  // explains too few matches (wrong prior, large motion, or no far structure), and whenever the
  // prior itself is the best candidate: a prior is only a guess from the previous frame, and
  // under parallax a wrong rotation plus a translation can explain a close scene almost as well as
  // the right one, so a prior that is never challenged by the data can carry an error from frame
  // to frame. Its biased modes are still good starting points for the translation-aware
  // refinement.
  for (int pass = 0; pass < 2; ++pass) {
    const bool narrow = pass == 0;
    const Eigen::Vector3d centre = narrow && prior_usable ? prior.rotation_vector : Eigen::Vector3d::Zero();
    const double window = narrow ? settings_.rotation_window_deg : settings_.wide_window_deg;
    // The histogram never exceeds kMaxRotationBins cells per axis (memory grows with their cube):
    // a bin too fine for its window is widened, so every setting in range is usable.
    const double bin = std::max(settings_.rotation_bin_deg, 2.0 * window / (narrow ? kMaxRotationBins : 40.0));
    for (int k = 0; k < 3; ++k) request.grid.centre[k] = static_cast<float>(centre[k]);
    request.grid.bin_width = static_cast<float>(bin * kDeg);
    request.grid.bins = binsFor(window, bin);
    request.triple = tripleOptions(settings_, false, narrow ? settings_.max_angle_change_deg : 0.0);
    request.seed = seed + (narrow ? 0 : 0x9E3779B97F4A7C15ull);
    VoteResult& votes = *votes_;
    castVotes(request, &votes);
    result.hypotheses_drawn += settings_.hypotheses;
    result.hypotheses_accepted += static_cast<int>(votes.accepted);
    const int winning = votes.winner >= 0 ? votes.histogram[votes.winner] : 0;
    result.winning_votes = std::max(result.winning_votes, winning);
    if (!narrow) diagnostics.wide_vote = true;
    for (const Candidate& c : topCandidates(votes, request.grid, settings_.candidates))
      consider(c.rotation_vector, narrow ? "narrow" : "wide");
    // The prior, and no rotation at all, are candidates too: under strong translation every
    // rotation-only triple is biased, and the truth is usually closer to one of them.
    if (narrow && prior_usable && partEnabled(VotePart::kPriorCandidate)) consider(prior.rotation_vector, "prior");
    if (narrow && partEnabled(VotePart::kIdentityCandidate)) consider(Eigen::Vector3d::Zero(), "identity");
    const bool prior_unchallenged = prior_usable && best_verified_is_prior;
    if (best_verified >= needed && result.winning_votes >= settings_.min_votes && !prior_unchallenged) break;
    if (!partEnabled(VotePart::kWideVote)) break;
  }
  if (best_verified == 0) return invalidResult(FrameStatus::kDegenerate, "no candidate rotation (all triples degenerate)");

  // Refine, then choose. The verification's count (a loose gate, a translation from a few
  // samples) ranks candidates only roughly: along the rotation/translation valley of a close scene
  // a rotation a degree off, with a translation that absorbs the difference, passes the loose gate
  // about as often as the right one. Refinement separates them: the right rotation converges to a
  // tight fit of most matches, the wrong one to a local minimum that keeps clearly fewer. So every
  // candidate with a comparable verified count is refined, and the refined count decides.
  std::stable_sort(verified.begin(), verified.end(), [](const Verified& a, const Verified& b) {
    return a.rotation.inliers > b.rotation.inliers;
  });
  RefinedRotation refined;
  const Verified* winner = nullptr;
  int refined_count = 0;
  std::vector<RefinedRotation> contenders;  // every refined candidate, the winner included
  for (const Verified& v : verified) {
    if (refined_count == (partEnabled(VotePart::kRefineContenders) ? kMaxRefinedCandidates : 1)) break;
    // The prior and the identity are refined whatever their verified count: they are candidates
    // because under strong translation the voted rotations are all biased alike, and then their
    // own verification (a translation sampled from a start far off) undercounts them too.
    const std::string_view source(v.source);
    const bool structural =
        partEnabled(VotePart::kRefineContenders) && (source == "prior" || source == "identity");
    if (v.rotation.inliers < kRefineFraction * best_verified && !structural) continue;
    const RefinedRotation r = refineRotation(matches, v.rotation, threshold, settings_.refine_iterations);
    ++refined_count;
    contenders.push_back(r);
    if (winner == nullptr || explainsBetter(r, refined)) {
      if (winner != nullptr) diagnostics.runner_up_inliers = std::max(diagnostics.runner_up_inliers, refined.inliers);
      refined = r;
      winner = &v;
    } else {
      diagnostics.runner_up_inliers = std::max(diagnostics.runner_up_inliers, r.inliers);
    }
  }
  // A later refinement challenges the winner: it joins the contenders (the covariance's spread) and
  // replaces the winner when it explains the matches better. True when it did.
  const auto challenge = [&](const RefinedRotation& r) {
    contenders.push_back(r);
    const bool wins = explainsBetter(r, refined);
    diagnostics.runner_up_inliers = std::max(diagnostics.runner_up_inliers, wins ? refined.inliers : r.inliers);
    if (wins) refined = r;
    return wins;
  };
  // The previous frame's motion, as a start of its own. Near structure a wrong rotation with a
  // wrong translation (forward instead of sideways, say) can explain the matches almost as well as
  // the right pair, and every voted candidate, each refined from the translation its verification
  // sampled, may start in that wrong basin; translation directions change little from frame to
  // frame, so the previous one, with the prior rotation, usually starts in the right basin. Not
  // needed when the winner already moves along (or against) that direction: it would converge to
  // the winner again (under forward driving, every frame).
  if (partEnabled(VotePart::kPreviousMotion) && prior_usable && prior.translation.allFinite() &&
      prior.translation.norm() > 0.5) {
    const Eigen::Vector3d previous_direction = prior.translation.normalized();
    const bool same_direction = !refined.pure_rotation && !refined.translation.isZero() &&
                                std::abs(refined.translation.normalized().dot(previous_direction)) >
                                    std::cos(kSameTranslationDeg * kDeg);
    if (!same_direction) {
      diagnostics.previous_motion_won = challenge(refineMotion(
          matches, so3Exp(prior.rotation_vector), previous_direction, threshold, settings_.refine_iterations));
    }
  }
  // Local optimisation: the refined rotation is better than the voted one, so the translation
  // search on it finds a better epipole and more inliers; repeat while the inlier set grows. Before
  // the valley search: a winner refined as a pure rotation (a translation that explained few more
  // matches than none) may turn out to have one here, and then its valley must be searched.
  for (int round = 1; round <= (partEnabled(VotePart::kReverify) ? 1 : 0); ++round) {
    const VerifiedRotation again = verifyRotation(matches, refined.rotation, threshold, seed + round);
    // A couple more inliers cannot move the solution measurably; only a clearly larger set is
    // worth another refinement.
    if (again.inliers <= refined.inliers + std::max(3, refined.inliers / 50)) break;
    const RefinedRotation next =
        refineRotation(matches, again, threshold, settings_.refine_iterations, true);
    if (next.inliers <= refined.inliers) break;
    refined = next;
  }
  // The valley of a close scene. A lateral translation t and a rotation about view x t move the
  // image alike, to first order; only the depth differences between the points tell them apart.
  // Candidates that start on the wrong side of that valley converge to its nearest local
  // minimum, a fraction of a degree to a few degrees from the right one, so the winner is
  // re-verified at rotations stepped along the valley (and at the minimum of the parabola through
  // the best step and its neighbours), and the best step, when it explains the matches more
  // tightly, is refined and competes. The valley is about view x t when the winner's translation
  // is lateral; a winner whose refinement lost much of its verified support may sit in a wrong
  // basin whose translation says nothing of the true valley, so then both axes across the view
  // are searched. Wrong matches alone do not trigger that: verification does not count them either.
  // Under forward motion with the matches explained there is no such valley and nothing runs.
  if (partEnabled(VotePart::kValley) && !refined.pure_rotation && !refined.translation.isZero()) {
    Eigen::Vector3d view = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& b : previous) view += b;
    view.normalize();
    std::vector<Eigen::Vector3d> axes;
    const Eigen::Vector3d lateral = view.cross(refined.translation);
    if (lateral.norm() >= kMinValleyLateral) axes.push_back(lateral.normalized());
    if (refined.inliers < kValleyInlierRatio * best_verified) {
      const Eigen::Vector3d across = view.cross(std::abs(view.x()) < 0.9 ? Eigen::Vector3d::UnitX()
                                                                        : Eigen::Vector3d::UnitY()).normalized();
      axes.push_back(across);
      axes.push_back(view.cross(across));
    }
    // Steps are ranked by their truncated cost, not by a count: along the valley the wrong rotation
    // and the right one keep nearly every match within the gate, and only how tightly tells them
    // apart.
    VerifiedRotation best_step;  // the best step, once one beats the winner
    double best_cost = 0.0;
    if (!axes.empty()) {
      best_cost = truncatedEpipolarCost(matches, refined.rotation, refined.translation, threshold);
      diagnostics.valley_searched = true;
    }
    bool stepped = false;
    // The cost of the winner turned by `step_deg` about `axis`, paired with its own translation
    // (the step's verification finds one; else the winner's); the best so far is kept.
    const double base_cost = best_cost;
    const auto tryStep = [&](const Eigen::Vector3d& axis, double step_deg) {
      const Eigen::Matrix3d stepped_rotation = so3Exp(step_deg * kDeg * axis) * refined.rotation;
      VerifiedRotation v = verifyRotation(matches, stepped_rotation, threshold, seed + 7);
      Eigen::Vector3d translation = v.translation.isZero() ? refined.translation : v.translation;
      const double cost = fittedTranslationCost(matches, stepped_rotation, &translation, threshold, kValleyRefits);
      v.translation = translation;
      if (cost < best_cost) {
        best_step = v;
        best_cost = cost;
        stepped = true;
      }
      return cost;
    };
    for (const Eigen::Vector3d& axis : axes) {
      // The steps' costs, the winner's own (step 0) in order among them.
      std::array<std::pair<double, double>, std::size(kValleySteps) + 1> costs;
      size_t k = 0;
      for (double step_deg : kValleySteps) {
        if (k > 0 && costs[k - 1].first < 0.0 && step_deg > 0.0) costs[k++] = {0.0, base_cost};
        costs[k++] = {step_deg, tryStep(axis, step_deg)};
      }
      // The valley's minimum lies between steps more often than on one: the parabola through the
      // lowest step and its neighbours puts it there.
      const size_t lowest = static_cast<size_t>(
          std::min_element(costs.begin(), costs.end(), [](const auto& a, const auto& b) { return a.second < b.second; }) -
          costs.begin());
      if (lowest == 0 || lowest + 1 == costs.size()) continue;
      const auto [x0, y0] = costs[lowest - 1];
      const auto [x1, y1] = costs[lowest];
      const auto [x2, y2] = costs[lowest + 1];
      const double denominator = (x1 - x0) * (y1 - y2) - (x1 - x2) * (y1 - y0);
      if (!(std::abs(denominator) > 0.0)) continue;
      const double vertex =
          x1 - 0.5 * ((x1 - x0) * (x1 - x0) * (y1 - y2) - (x1 - x2) * (x1 - x2) * (y1 - y0)) / denominator;
      if (vertex > x0 && vertex < x2 && vertex != x1) tryStep(axis, vertex);
    }
    if (stepped) {
      diagnostics.valley_moved =
          challenge(refineRotation(matches, best_step, threshold, settings_.refine_iterations));
    }
  }
  // Restarts over the translation directions. At large motion near structure (pairs several frames
  // apart, a prior degrees off) every voted rotation can be biased alike by the translation, every
  // candidate start in one wrong basin (a forward translation with a rotation degrees off, say),
  // and the previous direction may be far from this pair's: the winner then explains clearly fewer
  // matches than the right motion would, with a covariance as tight as a right one's. So when the
  // winner leaves more than a fifth of the matches unexplained, the general refinement also starts
  // from the winner's rotation with each of a few translation directions that cover the lines
  // through the camera, and each competes. Last, after the valley search: a winner the valley moved
  // into the right basin explains most matches and needs none of this. Frames whose matches are
  // mostly explained (every frame of a well-matched sequence) never run it; with many wrong
  // matches it runs on most frames, and there finds the translation that the verification's
  // samples, drawn among the wrong matches, missed.
  // Asked again before the descent: a restart may have replaced the winner.
  const auto explainsTooFew = [&] {
    return refined.inliers < kRestartInlierFraction * static_cast<double>(n);
  };
  if (partEnabled(VotePart::kRestarts) && explainsTooFew()) {
    // Besides the winner's rotation, the rotations of the refined contenders with the most inliers
    // that lie elsewhere: with many wrong matches near structure the winner can be a wrong basin
    // a degree or two from the right rotation, too far for any translation to bring the right
    // matches within the gate, while a contender sits in the right basin and lost only through
    // its translation.
    std::array<Eigen::Matrix3d, 1 + kRestartContenders> starts;
    starts[0] = refined.rotation;
    size_t start_count = 1;
    const auto elsewhere = [&](const Eigen::Matrix3d& rotation) {
      for (size_t k = 0; k < start_count; ++k)
        if (rotationAngleBetween(starts[k], rotation) < kRestartSeparationDeg * kDeg) return false;
      return true;
    };
    while (start_count < starts.size()) {
      const RefinedRotation* best = nullptr;
      for (const RefinedRotation& c : contenders)
        if ((best == nullptr || c.inliers > best->inliers) && elsewhere(c.rotation)) best = &c;
      if (best == nullptr) break;
      starts[start_count++] = best->rotation;
    }
    for (size_t k = 0; k < start_count; ++k) {
      for (const Eigen::Vector3d& direction : restartDirections()) {
        if (challenge(refineMotion(matches, starts[k], direction, threshold, settings_.refine_iterations)))
          diagnostics.restart_won = true;
      }
    }
  }
  // A descent on the truncated cost itself, under the same condition. Every refinement minimises
  // a Tukey cost under an adaptive gate; with many matches unexplained that cost has local minima
  // where it stops 0.1-0.7 deg short of the truncated cost's minimum (the criterion that chooses
  // between refinements), with the right translation already. Small steps on the truncated cost
  // cross them; a refinement from where they end gives a stationary point, and its covariance,
  // and competes like the others.
  if (partEnabled(VotePart::kDescent) && explainsTooFew() && !refined.pure_rotation &&
      !refined.translation.isZero()) {
    Eigen::Matrix3d rotation = refined.rotation;
    Eigen::Vector3d translation = refined.translation;
    if (descendTruncatedCost(matches, threshold, &rotation, &translation))
      diagnostics.descent_won =
          challenge(refineMotion(matches, rotation, translation, threshold, settings_.refine_iterations));
  }
  diagnostics.winner_source = diagnostics.descent_won           ? "descent"
                               : diagnostics.restart_won         ? "restart"
                               : diagnostics.previous_motion_won ? "previous_motion"
                                                                 : winner->source;
  const VerifiedRotation& best = winner->rotation;
  fillAngles(refined.rotation, &result);
  result.translation = refined.pure_rotation ? Eigen::Vector3d::Zero() : refined.translation;
  result.covariance = honestCovariance(matches, &workspace_->refit_matches, refined, contenders, threshold,
                                       settings_.refine_iterations, refined_positions_,
                                       partEnabled(VotePart::kRefitJackknife),
                                       partEnabled(VotePart::kContenderSpread), &diagnostics);
  for (int k = 0; k < 3; ++k)
    result.covariance(k, k) = std::max(result.covariance(k, k), settings_.min_covariance_rad2);
  result.inliers = refined.inliers;
  result.pure_rotation = refined.pure_rotation;
  diagnostics.rotation_inliers = best.rotation_inliers;
  diagnostics.epipolar_inliers = best.epipolar_inliers;
  diagnostics.residual_sigma = refined.residual_sigma;
  if (prior_usable) diagnostics.prior_offset = rotationAngleBetween(so3Exp(prior.rotation_vector), refined.rotation);
  if (match_footprint_ > 0.0)
    diagnostics.descriptor_areas =
        inlierHullArea(matches, refined, threshold) / (match_footprint_ * match_footprint_);

  result.status = FrameStatus::kValid;
  if (result.winning_votes < settings_.min_votes) {
    result.invalidate(FrameStatus::kFlatHistogram, "winning cell has " + std::to_string(result.winning_votes) +
                                                       " votes (need " + std::to_string(settings_.min_votes) + ")");
  } else if (refined.inliers < needed) {
    result.invalidate(FrameStatus::kTooFewInliers,
                      std::to_string(refined.inliers) + " inliers of " + std::to_string(n) + " matches");
  } else if (diagnostics.descriptor_areas < kMinDescriptorAreas) {  // false for NaN: no footprint, no check
    std::ostringstream why;
    why << "inliers too concentrated: their hull covers " << std::fixed << std::setprecision(1)
        << diagnostics.descriptor_areas << " descriptor patches (need " << std::defaultfloat << kMinDescriptorAreas
        << "; the image may be too small for the descriptor)";
    result.invalidate(FrameStatus::kTooFewInliers, why.str());
  }
  return result;
}

// ---------------------------------------------------------------------------------------------

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
  const std::string problem = validateSettings(settings);
  if (!problem.empty()) throw std::invalid_argument("invalid estimator settings: " + problem);
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
