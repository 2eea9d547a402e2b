// Frame-to-frame rotation from matched bearing vectors.
//
// Convention (the same in the voters, src/voter/hypothesis_math.h): R maps bearings of the current frame k into the previous
// frame k-1, b_prev ~ R b_cur; R = R_{k-1}^T R_k for camera poses R_k. Its rotation vector divided
// by the frame interval is the camera's angular velocity in the camera frame (what a gyro fixed to
// the camera measures). Angles in radians unless a name says _deg; times in milliseconds.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>

#include "visual_gyro/backend.h"
#include "visual_gyro/frame_status.h"
#include "visual_gyro/geometry.h"
#include "visual_gyro/setting_field.h"
#include <memory>
#include <string>
#include <vector>

namespace visual_gyro {

class HypothesisVoter;
struct VoteRequest;
struct VoteResult;
struct VoteWorkspace;

/// How the rotation is estimated.
enum class EstimationMethod {
  kVote,   ///< 3-D rotation voting, translation-aware verification and refinement
  kPaper,  ///< the paper's yaw-histogram voting, reproduced faithfully
};
/// Which hypothesis voter runs.
enum class BackendChoice {
  kAuto,  ///< CUDA when the build has it and a device works, else the CPU
  kCpu,
  kCuda,  ///< CUDA, or the CPU with one warning when unavailable
};
/// "vote" or "paper".
const char* methodName(EstimationMethod method);
/// "auto", "cpu" or "cuda".
const char* backendChoiceName(BackendChoice backend);
/// Reads a method name; false (and *method untouched) for an unknown one.
bool parseMethod(const std::string& name, EstimationMethod* method);
/// Reads a backend name; false (and *backend untouched) for an unknown one.
bool parseBackendChoice(const std::string& name, BackendChoice* backend);

/// Settings of the rotation estimator. Degrees in the settings, radians in the results. Ranges,
/// units and docs: estimatorSettingFields().
struct EstimatorSettings {
  EstimationMethod method = EstimationMethod::kVote;
  BackendChoice backend = BackendChoice::kAuto;
  int hypotheses = 2000;  ///< triples drawn per frame
  uint64_t seed = 1;      ///< Philox seed; frame f uses seed + f, so runs are reproducible

  // --- degeneracy tests (both methods) ---
  double min_separation_deg = 0.3;     ///< bearings of a triple closer than this are "repeated"
  double min_triangle_area_deg2 = 0.5;  ///< smaller triangles of a triple are "collinear" [deg^2]

  // --- paper method ---
  bool centroid_subtraction = true;  ///< subtract centroids before Arun's SVD (paper: yes)
  double yaw_bin_deg = 0.1;          ///< yaw histogram bin width
  double yaw_window_deg = 15.0;      ///< yaw histogram covers [-window, +window)

  // --- vote method ---
  /// Cell width of the 3-D rotation-vector histogram (widened to rotation_window_deg / 64 when
  /// finer: at most 128 cells per axis).
  double rotation_bin_deg = 0.5;
  double rotation_window_deg = 6.0;   ///< half width of the histogram around the prior
  double wide_window_deg = 30.0;      ///< half width of the fallback histogram (prior failed)
  double max_angle_change_deg = 0.5;  ///< triples whose pairwise angles change more are voted out
  int candidates = 2;                 ///< fullest cells verified against all matches
  double inlier_threshold_deg = 0.1;  ///< epipolar / rotation residual of an inlier
  bool use_prior = true;              ///< centre the vote window on the previous rotation
  int refine_iterations = 10;         ///< Gauss-Newton iterations of the refinement

  // --- validity ---
  int min_matches = 8;             ///< fewer matches: invalid result
  int min_votes = 5;               ///< winning cell with fewer votes: invalid
  double min_inlier_ratio = 0.15;  ///< vote method: fewer inliers: invalid
  double min_covariance_rad2 = 1e-8;  ///< floor of each rotation covariance diagonal entry
};

/// Standard deviation per axis [rad] added to every vote-method rotation covariance from refined
/// (sub-pixel) positions, 0.015 deg: the errors no residual shows (calibration, time stamps).
/// Calibrated once on kitti_turn, kitti_straight and euroc_mh01_shake together, with each truth's
/// own error in the evaluation (doc/covariance.md).
constexpr double kRefinedPositionsCovarianceFloor = 0.015 * kDegToRad;
/// The same for integer positions, 0.035 deg. FAST's integer corners shift alike under motion blur,
/// an error shared by every match that neither the residuals nor their spread show; this model
/// (with kIntegerPositionsEffectiveMatches) is conservative where there is no blur.
constexpr double kIntegerPositionsCovarianceFloor = 0.035 * kDegToRad;
/// Independent matches the covariance counts at most with integer positions (with refined
/// positions, the spatial jackknife measures them per frame).
constexpr double kIntegerPositionsEffectiveMatches = 40.0;
/// The floor for positions refined (true) or integer (false).
inline double rotationCovarianceFloor(bool refined_positions) {
  return refined_positions ? kRefinedPositionsCovarianceFloor : kIntegerPositionsCovarianceFloor;
}

/// Fewest descriptor patches the vote method's inliers must cover for a valid estimate: the area
/// of their convex hull on the image plane over the square of the angle a match's descriptor patch
/// spans (RotationEstimator::setMatchFootprint). A match is located by its patch, and matches
/// whose patches overlap share what biases a patch's position (a depth edge across it, its change
/// of scale under forward motion, blur). The spatial jackknife, from which the covariance takes
/// such shared errors, sees them only between groups of matches that share no patch. When all the
/// inliers lie within a few patches of one another (in a small image the descriptor's border
/// leaves a band across its middle), those errors neither average out nor show, and the estimate
/// is further off than its covariance says. The value 8 is measured on the shared sequences
/// downscaled (doc/covariance.md, Resolution): frames covering 8.2 patches and more were honest,
/// 5.9-7.1 patches over-confident.
constexpr double kMinDescriptorAreas = 8.0;

/// Every estimator setting with its range, unit and doc (see setting_field.h).
const std::vector<SettingField<EstimatorSettings>>& estimatorSettingFields();

/// Checks settings: every field in its range (estimatorSettingFields); there are no rules across
/// fields, so exactly the ranges are accepted. Returns "" when usable, else a message naming the
/// bad setting.
std::string validateSettings(const EstimatorSettings& settings);

/// Wall-clock time of one rotation estimate and its parts [ms].
struct EstimateTimes {
  double estimate = 0.0;  ///< the whole estimate = vote + refine
  /// Part of estimate spent in the hypothesis voter (host clock: for CUDA upload, kernels,
  /// download and result), summed over the voter calls of the estimate.
  double vote = 0.0;
  /// Part of vote spent in GPU kernels (CUDA events); 0 on the CPU backend.
  double vote_device = 0.0;
  /// Part of estimate outside the voter, on the host: reading the winner, verification and
  /// refinement (vote method), angles and covariance.
  double refine = 0.0;

  /// Adds another estimate's times (e.g. a second estimate of the same frame).
  EstimateTimes& operator+=(const EstimateTimes& other) {
    estimate += other.estimate;
    vote += other.vote;
    vote_device += other.vote_device;
    refine += other.refine;
    return *this;
  }
};

/// How the vote method reached its result, for per-frame diagnostics (evaluate --csv, the
/// RotationEstimate message). Counts refer to the candidate that won verification.
struct VoteDiagnostics {
  bool prior_used = false;  ///< the narrow vote window was centred on a prior
  bool wide_vote = false;   ///< the wide (prior-free) vote ran as well
  /// Where the winning candidate came from: "narrow" or "wide" (a vote cell), "prior" (the prior
  /// itself), "identity", "previous_motion" (the refinement started from the prior rotation and
  /// the previous frame's translation direction), "restart" (a refinement restarted from the
  /// winner's or a contender's rotation with another translation direction, when the winner
  /// explained too few matches), "descent" (a refinement from the end of a descent on the
  /// truncated cost, under the same condition), or "weak_support" (the pure rotation that replaced
  /// a general motion whose fit the matches' noise limits); "" when none was verified.
  std::string winner_source;
  int candidates_verified = 0;  ///< candidate rotations checked against all matches
  /// The rotation/translation valley of a close scene was searched (general motion with a
  /// lateral translation), and its search replaced the winner.
  bool valley_searched = false;
  bool valley_moved = false;
  /// The refinement started from the previous frame's motion (the prior rotation and the previous
  /// translation direction) won.
  bool previous_motion_won = false;
  /// A refinement restarted from the winner's or a contender's rotation with another translation
  /// direction (run when the winner explained too few of the matches) won.
  bool restart_won = false;
  /// The refinement from the end of the descent on the truncated cost (run after the restarts,
  /// under the same condition) won.
  bool descent_won = false;
  /// A general-motion winner whose fit the matches' noise limits (its residual sigma reaches the
  /// gate's) was replaced by the pure rotation, which keeps most of its inliers (the final choice
  /// of model where the support is weak).
  bool weak_support_pure = false;
  int rotation_inliers = 0;     ///< winner's matches explained by a pure rotation
  int epipolar_inliers = 0;     ///< winner's matches explained by rotation + translation
  /// Refined inliers of the best losing candidate; -1 when only the winner was refined.
  int runner_up_inliers = -1;
  /// Angle between the result and the prior [rad]; NaN without a prior.
  double prior_offset = std::numeric_limits<double>::quiet_NaN();
  /// Robust scale of the refined inliers' residuals [rad] (the sigma of the covariance).
  double residual_sigma = 0.0;
  /// Inliers the covariance counts as independent (at most the inliers). With refined positions,
  /// the inliers over the factor by which the spread of the rotation over spatial groups of them
  /// exceeds sigma^2 (J^T W J)^-1; with integer ones, at most kIntegerPositionsEffectiveMatches
  /// (RotationEstimator::setRefinedPositions; doc/covariance.md).
  double effective_matches = 0.0;
  /// Matches whose residual lies between one and three inlier gates, per inlier (refined positions
  /// only; 0 otherwise): how many matches are located a little worse than the inliers.
  double near_miss_share = 0.0;
  /// The covariance also took the spread of refits without each spatial group of the matches (run
  /// when near_miss_share is 0.1 or more; doc/covariance.md).
  bool refit_jackknife = false;
  /// Descriptor patches the inliers' convex hull covers on the image plane (its area over the
  /// squared match footprint; kMinDescriptorAreas); NaN when the footprint is unknown.
  double descriptor_areas = std::numeric_limits<double>::quiet_NaN();
  /// The rotation's change down the image [rad per unit of matchRow (geometry.h), camera frame], a
  /// rolling shutter's under a changing rate: match i's rotation is rotation * exp(s_i row_skew),
  /// the result's rotation that of the principal point's row. Zero where the matches did not call
  /// for one (a global shutter, as a rule).
  Eigen::Vector3d row_skew = Eigen::Vector3d::Zero();
};

/// Result of one rotation estimate.
struct RotationResult {
  /// kValid, or why there is no trustworthy rotation (then every rotation field is the identity).
  FrameStatus status = FrameStatus::kNotEstimated;
  std::string reason;  ///< details of a status other than kValid, for people ("" when valid)
  /// True when status is kValid.
  bool valid() const { return status == FrameStatus::kValid; }
  /// Marks the result invalid: sets status and reason and resets the rotation to the identity.
  void invalidate(FrameStatus why, const std::string& details);
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();        ///< b_prev ~ R b_cur
  Eigen::Quaterniond quaternion = Eigen::Quaterniond::Identity();  ///< same rotation (w, x, y, z)
  Eigen::Vector3d rotation_vector = Eigen::Vector3d::Zero();     ///< axis * angle [rad]
  double yaw = 0.0;    ///< about camera +y (down) [rad]; R = Ry(yaw) Rx(pitch) Rz(roll)
  double pitch = 0.0;  ///< about camera +x (right) [rad]
  double roll = 0.0;   ///< about camera +z (forward) [rad]
  /// Covariance of the rotation vector [rad^2], camera frame.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  /// Vote method: unit direction of the camera's translation in the previous camera frame, up to
  /// sign (the epipolar constraint does not fix it); zero for a pure rotation, an invalid result
  /// and the other methods.
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  int matches_used = 0;          ///< matches given to the estimator
  int hypotheses_drawn = 0;      ///< triples drawn
  int hypotheses_accepted = 0;   ///< triples that voted (non-degenerate, inside the window)
  int winning_votes = 0;         ///< votes of the winning cell
  int inliers = 0;               ///< matches consistent with the result (vote method; paper: 0)
  bool pure_rotation = false;    ///< vote method: the matches are explained by rotation alone
  Backend backend = Backend::kCpu;  ///< backend that voted
  VoteDiagnostics diagnostics;   ///< vote method: how the result was reached
  EstimateTimes times;           ///< time of this estimate
};

/// Optional prior for one estimate: the previous frame's rotation, scaled to this interval.
struct RotationPrior {
  bool valid = false;
  Eigen::Vector3d rotation_vector = Eigen::Vector3d::Zero();  ///< [rad]
  /// The previous frame's unit translation direction (RotationResult::translation); zero when
  /// unknown. Translation directions change little between frames, so it starts one more
  /// refinement of the vote method near structure.
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
};

/// Remembers the last valid rotation and offers it as the next frame's prior, rescaled to the new
/// frame interval (rotation rates change little between frames, rotations per frame change with
/// the interval). An invalid estimate clears it.
class PriorTracker {
 public:
  /// The prior for a frame `dt` seconds after the previous one (invalid when there is none).
  RotationPrior priorFor(double dt) const;
  /// Records the estimate of a frame `dt` seconds after its predecessor.
  void update(const RotationResult& result, double dt);
  void reset() { *this = PriorTracker(); }

 private:
  RotationPrior last_;
  double last_dt_ = 0.0;
};

/// Parts of the vote method that can be switched off one at a time, to measure on `make score`
/// what each earns (evaluate's `vote-without-<part>` methods; doc/evaluation.md's ablation).
/// Every part is on unless RotationEstimator::setDisabledParts says otherwise; not a setting.
enum class VotePart : uint8_t {
  kWideVote,          ///< the prior-free wide vote when the narrow one explains too few matches
  kPriorCandidate,    ///< the prior itself as a candidate
  kIdentityCandidate, ///< no rotation as a candidate
  kRefineContenders,  ///< refining every comparable candidate, not only the best-verified one
  kPreviousMotion,    ///< the refinement from the prior rotation and the previous translation
  kValley,            ///< the search along the rotation/translation valley of a close scene
  kRestarts,          ///< refinements from 13 translation directions when too few are explained
  kDescent,           ///< the descent on the truncated cost under the same condition
  kRefitJackknife,    ///< the covariance's refits without each group (many near misses)
  kContenderSpread,   ///< the covariance's spread of the competing refined candidates
  kRowSkew,           ///< a pure rotation's change down the image (a rolling shutter's)
  kTranslationSpread, ///< a pure rotation's covariance covering what an unmodelled translation moves
  kContenderMean,     ///< the estimate as the likelihood-weighted mean of the refinements of its model
  kWeakSupport,       ///< a pure rotation for a general motion whose fit is noise-limited, where it keeps most
  kCount
};
/// The part's name in `vote-without-<name>` ("wide_vote", "prior_candidate", ...).
const char* votePartName(VotePart part);
/// Parses a votePartName(); false when `name` names no part.
bool parseVotePart(const std::string& name, VotePart* part);

/// Estimates the frame-to-frame rotation from matched unit bearings. Not thread-safe; one per
/// stream of frames. Never throws on bad input: it returns an invalid result whose status names the problem.
class RotationEstimator {
 public:
  /// Uses `voter` for the hypotheses; see createRotationEstimator for the usual way to make one.
  RotationEstimator(const EstimatorSettings& settings, std::unique_ptr<HypothesisVoter> voter);
  ~RotationEstimator();

  /// previous[i] (frame k-1) and current[i] (frame k) are one match, unit vectors.
  RotationResult estimate(const std::vector<Eigen::Vector3d>& previous,
                          const std::vector<Eigen::Vector3d>& current,
                          const RotationPrior& prior = RotationPrior());
  /// After estimate(): another estimate for the same frame from other matches (the pipeline's
  /// half-resolution matches). It draws with that frame's seed and does not count as a frame, so the
  /// frames after it draw as if it had not run.
  RotationResult estimateSameFrame(const std::vector<Eigen::Vector3d>& previous,
                                   const std::vector<Eigen::Vector3d>& current,
                                   const RotationPrior& prior = RotationPrior());

  /// Changes settings (e.g. from dynamic_reconfigure); the backend stays.
  void setSettings(const EstimatorSettings& settings);
  /// Whether the matches' image positions are refined to sub-pixel precision (false: integer
  /// pixels, the default). It chooses the vote method's covariance model: refined positions count
  /// as many independent matches as a spatial jackknife of the inliers measures, integer ones at
  /// most kIntegerPositionsEffectiveMatches (rotationCovarianceFloor). Set by whoever runs the
  /// front end (VisualGyro from FrontEndSettings::subpixel_refinement), not a user setting.
  void setRefinedPositions(bool refined) { refined_positions_ = refined; }
  bool refinedPositions() const { return refined_positions_; }
  /// Angle [rad] a match's descriptor patch spans in the matches' images (matchFootprint() of the
  /// camera; twice that for half-resolution matches). The vote method's estimate is invalid
  /// (kTooFewInliers) when its inliers cover fewer than kMinDescriptorAreas such patches. 0, the
  /// default: unknown, no such check. A value that is not finite and positive counts as 0.
  void setMatchFootprint(double angle) { match_footprint_ = std::isfinite(angle) && angle > 0.0 ? angle : 0.0; }
  double matchFootprint() const { return match_footprint_; }
  /// Forgets what the stream has shown of its camera (whether it has a rolling shutter), for a new
  /// camera model.
  void forgetCamera() { skew_significance_.clear(); }
  /// Switches parts of the vote method off (bit k: VotePart k off); 0, the default, runs them all.
  /// Only for measuring what each part earns.
  void setDisabledParts(uint32_t mask) { disabled_parts_ = mask; }
  /// Whether `part` runs.
  bool partEnabled(VotePart part) const { return (disabled_parts_ >> static_cast<int>(part) & 1u) == 0; }
  const EstimatorSettings& settings() const { return settings_; }
  /// The backend that votes (backendName() prints it).
  Backend backend() const { return backend_; }
  /// Frames estimated so far (frame f draws with seed + f).
  uint64_t frameCount() const { return frame_count_; }

 private:
  RotationResult estimatePaper(const std::vector<Eigen::Vector3d>& previous,
                               const std::vector<Eigen::Vector3d>& current);
  RotationResult estimateVote(const std::vector<Eigen::Vector3d>& previous,
                              const std::vector<Eigen::Vector3d>& current, const RotationPrior& prior);

  /// voter_->vote, with its host and device time added to the frame's vote times.
  void castVotes(const VoteRequest& request, VoteResult* votes);
  /// Adds a frame's row-skew significance to the window; whether the skew is to be fitted.
  bool rollingShutterSeen(double significance);

  EstimatorSettings settings_;
  bool refined_positions_ = false;
  double match_footprint_ = 0.0;
  uint32_t disabled_parts_ = 0;
  std::unique_ptr<HypothesisVoter> voter_;
  Backend backend_ = Backend::kCpu;  // voter_'s
  double vote_ms_ = 0.0;         // this frame's voter time so far (host clock)
  double vote_device_ms_ = 0.0;  // this frame's kernel time so far
  std::unique_ptr<VoteResult> votes_;  // reused: no per-frame allocation once the histogram has its size
  std::unique_ptr<VoteWorkspace> workspace_;  // the vote method's per-frame arrays, reused likewise
  uint64_t frame_count_ = 0;
  std::vector<double> skew_significance_;  // the last frames' row-skew significance, oldest first
  uint64_t skew_significance_frame_ = 0;   // frame_count_ when its last entry was added
};

/// Receives the factory's one warning (e.g. "CUDA unavailable: ...; using the CPU").
using WarningSink = std::function<void(const std::string&)>;

/// Picks the backend named by settings.backend: "cpu"; "cuda" or "auto" (the default): CUDA when
/// the build has it and a device works, else the CPU with one warning through `warn` saying why
/// (an "auto" build without CUDA compiled in uses the CPU silently).
/// Throws std::invalid_argument for an unknown backend name.
std::unique_ptr<RotationEstimator> createRotationEstimator(const EstimatorSettings& settings,
                                                           const WarningSink& warn = WarningSink());

/// True when this build has the CUDA backend compiled in.
bool cudaBackendCompiled();

/// True when backend "auto" would pick CUDA here: the build has it and device 0 works (driver,
/// compute capability >= 7.5, kernels loadable). Otherwise false with the reason in *why (may be
/// null), e.g. "this build has no CUDA support" or "no usable CUDA device: ...".
bool cudaBackendUsable(std::string* why = nullptr);

}  // namespace visual_gyro
