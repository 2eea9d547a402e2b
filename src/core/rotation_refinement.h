// Verification and refinement of a candidate rotation against all matches (vote method).
// Private to src/core. Conventions as in rotation_estimator.h: b_prev ~ R b_cur.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "visual_gyro/calibration_fit.h"

namespace visual_gyro {

/// One frame's matches as structure-of-arrays, filled once per frame and read by every
/// verification and refinement of that frame, together with the scratch space those passes reuse.
/// Not thread-safe: one per estimator. Allocates only while its capacity grows.
class FrameMatches {
 public:
  /// Copies the bearings (previous[i] <-> current[i], equal sizes).
  void assign(const std::vector<Eigen::Vector3d>& previous, const std::vector<Eigen::Vector3d>& current);
  /// Copies the matches of `from` whose `group` entry is not `left_out`, in index order.
  void assignWithout(const FrameMatches& from, const std::vector<int>& group, int left_out);
  size_t size() const { return px.size(); }
  Eigen::Vector3d previous(size_t i) const { return Eigen::Vector3d(px[i], py[i], pz[i]); }
  Eigen::Vector3d current(size_t i) const { return Eigen::Vector3d(cx[i], cy[i], cz[i]); }

  /// Coordinates of the bearings in the previous (p*) and the current (c*) frame.
  std::vector<double> px, py, pz, cx, cy, cz;
  /// Every match as the summing passes read gathered ones (in the order passes::gatheredPosition
  /// gives, padded with zero bearings to whole chunks); filled when first needed (all_gathered).
  std::vector<double> all_px, all_py, all_pz, all_cx, all_cy, all_cz;
  bool all_gathered = false;

  /// Scratch of the verification and refinement passes (contents undefined between calls).
  struct Scratch {
    std::vector<double> rx, ry, rz;  ///< R b_cur
    std::vector<double> nx, ny, nz;  ///< b_prev x R b_cur
    /// b_prev . R b_cur: positive when both are in the same hemisphere (the match is usable).
    std::vector<double> facing;
    std::vector<double> residuals;  ///< squared residuals (the adaptive gate's median)
    /// Per-match results of the last pass over all matches (weights, squared residuals).
    std::vector<double> weights;
    /// The matches a refinement pass sums over, gathered contiguously (b_prev, then b_cur; in the
    /// order passes::gatheredPosition gives) and padded with zero bearings to whole chunks.
    std::vector<double> gpx, gpy, gpz, gcx, gcy, gcz;
    size_t gathered = 0;  ///< matches gathered, without the padding
    /// The rotation rx..facing belong to (valid when `rotated`): a pass at an unchanged rotation
    /// is skipped.
    Eigen::Matrix3d rotation;
    bool rotated = false;
    /// The usable matches at `rotation` as the translation counts read them (valid when
    /// `counting`): those of even index from 0 (even_count of them), those of odd index from
    /// odd_start (odd_count), each group in index order (n = b_prev x R b_cur, b_prev, R b_cur).
    std::vector<double> qnx, qny, qnz, qpx, qpy, qpz, qrx, qry, qrz;
    size_t even_count = 0, odd_start = 0, odd_count = 0;
    bool counting = false;
    std::vector<uint32_t> moving;  ///< matches a pure rotation does not explain (verification)
    /// The jackknife's inliers, ordered into spatial groups, and each match's group (-1: none).
    std::vector<uint32_t> order;
    std::vector<int> group;
    std::vector<uint32_t> all_order;  ///< the refit jackknife's matches, ordered into spatial groups
    std::vector<int> all_group;       ///< the refit jackknife's group of each match
    /// The inliers on the previous frame's normalised image plane, and their convex hull
    /// (inlierHullArea).
    std::vector<std::array<double, 2>> plane, hull;
  };
  Scratch scratch;

 private:
  /// Empties the matches and resets what was derived from them.
  void clear();
  /// Adds one match: its unit bearings in the previous and the current frame.
  void append(const Eigen::Vector3d& previous, const Eigen::Vector3d& current);
};

/// A candidate rotation checked against every match.
struct VerifiedRotation {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  /// Translation direction (unit, previous frame) best supported given the rotation; zero when the
  /// matches carry no translation information.
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  int inliers = 0;           ///< max of the two counts below
  int epipolar_inliers = 0;  ///< angular distance from the epipolar plane < threshold
  int rotation_inliers = 0;  ///< |b_prev x R b_cur| < threshold (pure rotation explains them)
};

/// Counts the matches consistent with `rotation`, both as a pure rotation and as a rotation plus
/// the translation direction found by a small 2-point RANSAC on the epipolar-plane normals
/// n_i = b_prev_i x R b_cur_i, which must all be orthogonal to the translation. A match is an
/// epipolar inlier when its angular distance from the epipolar plane (t . n_i over the Sampson
/// norm of its gradient) is below threshold [rad].
VerifiedRotation verifyRotation(FrameMatches& matches, const Eigen::Matrix3d& rotation, double threshold,
                                uint64_t seed);

/// The truncated quadratic cost [rad^2] of `rotation` with the unit translation direction
/// *translation (previous frame) over all the matches: each match's squared angular distance from
/// its epipolar plane, at most threshold^2 (also for a match behind either camera). Lower is a
/// tighter explanation; comparable between rotations of one frame at one threshold. The
/// translation is first refitted by least squares over the inliers (at most `refits` times, each
/// kept only when it lowers the cost); *translation becomes the one costed. A rotation's cost at
/// its own fitted translation, not at a sampled one, is what compares it fairly with a refined
/// rotation.
double fittedTranslationCost(FrameMatches& matches, const Eigen::Matrix3d& rotation, Eigen::Vector3d* translation,
                             double threshold, int refits);

/// The robust standard deviations of the residuals that a refinement's adaptive inlier gate spans
/// (clamped to [threshold / 8, threshold]). A fit whose residual sigma times this reaches the
/// threshold is limited by the noise of its matches: its gate can narrow no further.
constexpr double kGateSigmas = 3.5;

/// The refined rotation with its uncertainty.
struct RefinedRotation {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();  ///< rotation vector [rad^2]
  int inliers = 0;
  bool pure_rotation = false;  ///< refined as a pure rotation (no usable translation)
  /// Unit translation direction in the previous frame (general motion); zero for pure rotation.
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  /// How the rotation vector changes down the image [rad per unit of normalised row y / z], as a
  /// rolling shutter shows it while the rate changes within the pair. Match i's
  /// rotation is rotation * exp(s_i row_skew), s_i its mean normalised row over both views, so
  /// `rotation` is that of the principal point's row. Zero unless fitRowSkew fitted it.
  Eigen::Vector3d row_skew = Eigen::Vector3d::Zero();
  double residual_sigma = 0.0;  ///< RMS residual of the inliers [rad] (the covariance's sigma)
  /// Truncated quadratic cost over all the frame's matches [rad^2]: each inlier's squared residual,
  /// each other match the squared gate (MSAC's score, Torr and Zisserman). Comparable between
  /// refinements of one frame under the same model.
  double truncated_cost = 0.0;
  /// How closely the matches fix a general motion's translation direction [rad]: the larger
  /// standard deviation of its two tangent-plane parameters under the fit's statistical covariance
  /// (sigma^2 (J^T J)^-1, the rotation marginalised out). Zero for a pure rotation.
  double translation_sigma = 0.0;
  int matches = 0;  ///< the frame's matches, those the fit chose its inliers among
};

/// True when `r` is a general motion: refined with a translation, not as a pure rotation.
inline bool isGeneralMotion(const RefinedRotation& r) { return !r.pure_rotation && !r.translation.isZero(); }

/// True when refinement `a` explains the matches better than `b`: a lower truncated cost under the
/// same model (a count of inliers saturates when the gate is wide against the residuals, as it is
/// along the rotation/translation valley of a close scene, where the wrong rotation and the right
/// one both keep nearly every match but not equally tightly); between the models, the model choice
/// of refineRotation: a general motion (two more degrees of freedom) wins when its translation
/// explains clearly more matches than the pure rotation does, 15 % of its inliers more, or
/// significantly more than half of the matches the pure rotation leaves unexplained.
bool explainsBetter(const RefinedRotation& a, const RefinedRotation& b);

/// How strongly a rigid refinement's matches call for a row skew (RefinedRotation::row_skew):
/// Hotelling's T^2 = e^T S^-1 e of the one Gauss-Newton step e from the rigid fit in the skew's
/// model, S the spread of that step over a 16-group spatial jackknife of the inliers. 0 where it
/// exceeds kRowSkewSignificance but the left and the right half of the view (8 groups each, each
/// with its own rotation) call for skews that differ beyond it in the same statistic: a rolling
/// shutter acts on every column alike, an independently moving object on its own. NaN with fewer
/// inliers than the 16 groups need (160).
double rowSkewSignificance(FrameMatches& matches, const RefinedRotation& rigid, double threshold);

/// The rowSkewSignificance beyond which the matches call for a skew: Hotelling's T^2 at 99.9 % for
/// three parameters and 16 groups, 3 * 15 / 13 * F(3, 13; 0.999).
constexpr double kRowSkewSignificance = 35.3;
/// Frames (with a judged significance) over which a stream's rolling shutter is judged: the median
/// of their rowSkewSignificance exceeds kRowSkewSignificance on a rolling-shutter camera (the
/// calibration check's window), and every frame with a judged significance then takes the skew.
constexpr size_t kRowSkewWindowFrames = kFitWindowFrames;
/// Frames judged before the first skew: the window's median is read from this many frames on.
constexpr size_t kRowSkewMinFrames = 5;

/// Fits the row skew to a refinement: Gauss-Newton (pure rotation, Huber weights) or
/// Levenberg-Marquardt (general motion, with the translation, Tukey weights) on the skew's model
/// from the rigid fit, at its adaptive gate. The rotation becomes that of the principal point's row
/// and the covariance the rotation's block with the skew (and the translation) marginalised out;
/// inliers and truncated_cost stay the rigid fit's, which the model choice reads. False, and
/// *refined unchanged, where the rows do not determine the skew.
bool fitRowSkew(FrameMatches& matches, RefinedRotation* refined, double threshold);

/// Refines a verified rotation on its inliers. When a pure rotation explains (nearly) as many
/// matches as rotation + translation, minimises the angular residuals |b_prev x R b_cur| (robust
/// Kabsch); otherwise minimises the epipolar residuals t . (b_prev x R b_cur) over R and the unit
/// t jointly (Levenberg-Marquardt, Tukey weights) -- Kneip & Lynen's eigenvalue cost
/// lambda_min(sum n n^T), which is this cost minimised over t -- with each residual normalised to
/// an angle (Sampson). Covariance = sigma^2 (J^T W J)^-1 for the rotation, t marginalised.
RefinedRotation refineRotation(FrameMatches& matches, const VerifiedRotation& start, double threshold,
                               int iterations);

/// Refines `rotation` and the unit `translation` jointly as a general motion (refineRotation's
/// epipolar refinement, without its model selection): for a start that comes from elsewhere than
/// a verification, such as the previous frame's translation direction.
RefinedRotation refineMotion(FrameMatches& matches, const Eigen::Matrix3d& rotation,
                             const Eigen::Vector3d& translation, double threshold, int iterations);

/// Fewest inliers a jackknife group holds (the groups per axis shrink until each has this many).
constexpr int kMinJackknifeGroupSize = 10;

/// Area of the convex hull of the inliers of `refined` (jackknifeSpread's: residual within the
/// inlier gate of refineRotation's covariance) on the previous frame's normalised image plane
/// (x / z, y / z of the previous bearings; squared radians near the optical axis, where the plane
/// is tangent to the sphere of directions). Bearings less than kMinHullDepth in front of the
/// camera (more than ~84 deg off its axis) are left out. 0 for fewer than three inliers.
double inlierHullArea(FrameMatches& matches, const RefinedRotation& refined, double threshold);
/// z of the bearings inlierHullArea leaves out below: the plane stretches without bound towards
/// 90 deg off the axis.
constexpr double kMinHullDepth = 0.1;

/// Delete-a-group jackknife of a refined rotation.
struct JackknifeSpread {
  /// Covariance [rad^2] of the rotation vector (right perturbation, as RefinedRotation::covariance)
  /// from how far the rotation moves when each group is left out; zero when `groups` is 0.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  int groups = 0;  ///< groups of inliers used; 0 when the inliers are too few to form four
  /// Usable matches whose residual lies between the inlier gate and kNearMissGates times it, over
  /// the inliers (set whether or not the groups formed): 0 when the inliers' residuals have a
  /// Gaussian core and every other match is a gross outlier; large when many matches are located
  /// a little worse than the inliers (dim, noisy or blurred images), so that which of them the
  /// gate keeps moves the solution.
  double near_miss_share = 0.0;
};

/// The multiple of the inlier gate up to which JackknifeSpread::near_miss_share counts a match.
constexpr double kNearMissGates = 3.0;

/// The spread of `refined` over spatial groups of its inliers. The inliers (under the residual and
/// gate of refineRotation's covariance) are split into k x k groups of equal count by the previous
/// bearing: k strips across x, each cut into k along y, with k = 4 at most and at least
/// kMinJackknifeGroupSize inliers a group. Each group is left out in turn, one Gauss-Newton step
/// from the solution, and the spread of those steps estimates the rotation's covariance. Unlike
/// sigma^2 (J^T W J)^-1 it sees errors that neighbouring matches share (the same texture, blur or
/// rounding), since a group's matches leave together.
JackknifeSpread jackknifeSpread(FrameMatches& matches, const RefinedRotation& refined, double threshold);

/// The spread of the rotation over refits without each spatial group of all the matches: the
/// matches (inliers or not) split into k x k groups of equal count by the previous bearing as in
/// jackknifeSpread (at least kMinJackknifeGroupSize matches a group, k = 4 at most); each group is
/// left out in turn and the rest refined again from `refined` (refineMotion for a general motion,
/// refineRotation's pure-rotation refinement otherwise, `iterations` each), gate and inliers chosen anew.
/// Unlike jackknifeSpread, whose steps keep the inliers fixed, it sees how much the choice of
/// inliers moves the solution. `rest` holds each refit's matches (its capacity is reused).
JackknifeSpread refitJackknifeSpread(FrameMatches& matches, FrameMatches* rest, const RefinedRotation& refined,
                                     double threshold, int iterations);

}  // namespace visual_gyro
