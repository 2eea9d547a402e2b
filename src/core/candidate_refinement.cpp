// Refinement of the vote method's candidates and the searches for a better basin.
#include "candidate_refinement.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>
#include <utility>

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
// A winner explaining fewer than this fraction of the matches is refined again from several
// translation directions. Below it lie frames whose every candidate may share one wrong basin;
// above it, frames where the right motion already explains nearly every correct match (on the
// rendered close scene the right motion explains 94-97 % of the matches).
constexpr double kRestartInlierFraction = 0.8;
// Refined contenders whose rotations the restarts also start from, and how far [deg] a start must
// lie from every other start (nearer ones converge alike).
constexpr size_t kRestartContenders = 2;
constexpr double kRestartSeparationDeg = 0.3;
// A winner whose translation lies within this angle [deg] of the previous frame's (as lines) skips
// the refinement from the previous motion: it would converge to the winner again.
constexpr double kSameTranslationDeg = 10.0;
// The descent on the truncated cost: its step sizes about the camera axes [deg], coarse to fine,
// and the most moves at each.
constexpr std::array<double, 4> kDescentStepsDeg = {0.2, 0.1, 0.05, 0.025};
constexpr int kDescentMovesPerStep = 20;

// Translation starts of the restarts: unit directions in the camera frame (z forward), one per
// line through the camera, since a translation is only known up to sign: the 13 axes of a cube's
// symmetry (its 3 face normals, 6 edge midpoints and 4 corners), so that every line lies within
// 27.6 deg of one. Without the corners a line could lie 35 deg from every start, and a refinement
// from a rotation degrees off (near structure, many matches wrong) did not reach it.
const std::array<Eigen::Vector3d, 13>& restartDirections() {
  static const std::array<Eigen::Vector3d, 13> directions = [] {
    const double h = std::sqrt(0.5);
    const double c = std::sqrt(1.0 / 3.0);
    return std::array<Eigen::Vector3d, 13>{
        Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 0, 0),  Eigen::Vector3d(0, 1, 0),
        Eigen::Vector3d(h, h, 0), Eigen::Vector3d(h, -h, 0), Eigen::Vector3d(h, 0, h),
        Eigen::Vector3d(-h, 0, h), Eigen::Vector3d(0, h, h), Eigen::Vector3d(0, -h, h),
        Eigen::Vector3d(c, c, c), Eigen::Vector3d(-c, c, c), Eigen::Vector3d(c, -c, c), Eigen::Vector3d(-c, -c, c)};
  }();
  return directions;
}

// The axes of the valley search: view x t when the translation is lateral enough, and both axes
// across the view when the winner lost much of its verified support (a wrong basin, whose
// translation says nothing of the true valley). Wrong matches alone do not trigger that:
// verification does not count them either.
std::vector<Eigen::Vector3d> valleyAxes(const RefinedRotation& winner, const Eigen::Vector3d& view, int best_verified) {
  std::vector<Eigen::Vector3d> axes;
  const Eigen::Vector3d lateral = view.cross(winner.translation);
  if (lateral.norm() >= kMinValleyLateral) axes.push_back(lateral.normalized());
  if (winner.inliers < kValleyInlierRatio * best_verified) {
    const Eigen::Vector3d across =
        view.cross(std::abs(view.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY()).normalized();
    axes.push_back(across);
    axes.push_back(view.cross(across));
  }
  return axes;
}

// The minimum of the parabola through the lowest of `costs` ((step, cost), steps ascending) and its
// neighbours; false when the lowest is at an end or the three are collinear.
bool parabolaVertex(const std::array<std::pair<double, double>, std::size(kValleySteps) + 1>& costs, double* vertex) {
  const size_t lowest = static_cast<size_t>(
      std::min_element(costs.begin(), costs.end(), [](const auto& a, const auto& b) { return a.second < b.second; }) -
      costs.begin());
  if (lowest == 0 || lowest + 1 == costs.size()) return false;
  const auto [x0, y0] = costs[lowest - 1];
  const auto [x1, y1] = costs[lowest];
  const auto [x2, y2] = costs[lowest + 1];
  const double denominator = (x1 - x0) * (y1 - y2) - (x1 - x2) * (y1 - y0);
  if (!(std::abs(denominator) > 0.0)) return false;
  *vertex = x1 - 0.5 * ((x1 - x0) * (x1 - x0) * (y1 - y2) - (x1 - x2) * (x1 - x2) * (y1 - y0)) / denominator;
  return *vertex > x0 && *vertex < x2 && *vertex != x1;
}

// The steps of the valley search, ranked by their truncated cost, not by a count: along the
// valley the wrong rotation and the right one keep nearly every match within the gate, and only
// how tightly tells them apart. Each step is costed with its own translation (its verification
// finds one, else the winner's), refitted.
class ValleySteps {
 public:
  ValleySteps(FrameMatches& matches, const RefinedRotation& winner, double threshold, uint64_t seed)
      : matches_(matches), winner_(winner), threshold_(threshold), seed_(seed),
        winner_cost_(costAtOwnTranslation(matches, winner, threshold)),
        best_cost_(winner_cost_) {}

  // Every step about `axis`, then the parabola's vertex between the lowest and its neighbours
  // (the valley's minimum lies between steps more often than on one).
  void searchAxis(const Eigen::Vector3d& axis) {
    std::array<std::pair<double, double>, std::size(kValleySteps) + 1> costs;
    size_t k = 0;
    for (double step_deg : kValleySteps) {
      if (k > 0 && costs[k - 1].first < 0.0 && step_deg > 0.0) costs[k++] = {0.0, winner_cost_};
      costs[k++] = {step_deg, tryStep(axis, step_deg)};
    }
    double vertex = 0.0;
    if (parabolaVertex(costs, &vertex)) tryStep(axis, vertex);
  }
  // The best step, when one costs less than the winner.
  const VerifiedRotation* best() const { return stepped_ ? &best_step_ : nullptr; }

 private:
  static double costAtOwnTranslation(FrameMatches& matches, const RefinedRotation& r, double threshold) {
    Eigen::Vector3d translation = r.translation;
    return fittedTranslationCost(matches, r.rotation, &translation, threshold, 0);
  }

  double tryStep(const Eigen::Vector3d& axis, double step_deg) {
    const Eigen::Matrix3d rotation = so3Exp(step_deg * kDeg * axis) * winner_.rotation;
    VerifiedRotation v = verifyRotation(matches_, rotation, threshold_, seed_ + 7);
    Eigen::Vector3d translation = v.translation.isZero() ? winner_.translation : v.translation;
    const double cost = fittedTranslationCost(matches_, rotation, &translation, threshold_, kValleyRefits);
    v.translation = translation;
    if (cost < best_cost_) {
      best_step_ = v;
      best_cost_ = cost;
      stepped_ = true;
    }
    return cost;
  }

  FrameMatches& matches_;
  const RefinedRotation& winner_;
  const double threshold_;
  const uint64_t seed_;
  const double winner_cost_;
  double best_cost_;
  VerifiedRotation best_step_;
  bool stepped_ = false;
};

// Where the descent runs, and the restarts: a general-motion winner explaining fewer matches than
// they accept. A pure rotation's model choice found no translation worth its two parameters, and
// more tries at one only raise the odds that a translation chosen among wrong matches clears the
// margin (a dim, blurred room's pure frame of 100 matches: 69 inliers against a restart's 82).
bool generalWinnerExplainsTooFew(const FrameMatches& matches, const RefinedRotation& winner) {
  if (!isGeneralMotion(winner)) return false;
  return winner.inliers < kRestartInlierFraction * static_cast<double>(matches.size());
}

// Where the restarts also run: a general-motion winner whose translation its own fit leaves loose
// (kWeakTranslationSigmaDeg). A camera moved by centimetres among things metres away has several
// basins of the translation, each explaining nearly every match (a dim room: 92-95 % each, the one
// nearest the truth 17 % cheaper than the one every candidate reached, 0.3 deg off), which the
// share of matches explained never tells apart.
bool generalWinnerTranslationIsWeak(const RefinedRotation& winner) {
  if (!isGeneralMotion(winner)) return false;
  return winner.translation_sigma > kWeakTranslationSigmaDeg * kDeg;
}

// The best of the six steps of `step_deg` about the camera axes from (*rotation, *translation),
// each with its translation refitted; taken when it costs less than `cost`. True when it moved.
bool descentMove(FrameMatches& matches, double threshold, double step_deg, double* cost, Eigen::Matrix3d* rotation,
                 Eigen::Vector3d* translation) {
  double best_cost = *cost;
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
  if (!(best_cost < *cost)) return false;
  *cost = best_cost;
  *rotation = best_rotation;
  *translation = best_translation;
  return true;
}

}  // namespace

bool RefinementChoice::challenge(const RefinedRotation& r) {
  contenders.push_back(r);
  const bool wins = explainsBetter(r, winner);
  runner_up_inliers = std::max(runner_up_inliers, wins ? winner.inliers : r.inliers);
  if (wins) winner = r;
  return wins;
}

// The verification's count (a loose gate, a translation from a few samples) ranks candidates only
// roughly: along the rotation/translation valley of a close scene a rotation a degree off, with a
// translation that absorbs the difference, passes the loose gate about as often as the right one.
// Refinement separates them: the right rotation converges to a tight fit of most matches, the
// wrong one to a local minimum that keeps clearly fewer. So every candidate with a comparable
// verified count is refined, and the refined count decides. The prior and the identity are refined
// whatever their verified count: under strong translation the voted rotations are all biased alike,
// and then the prior's and the identity's own verification (a translation sampled from a start
// far off) undercounts them too.
RefinementChoice refineCandidates(FrameMatches& matches, const CandidateVote& vote, double threshold, int iterations,
                                  bool all_contenders) {
  RefinementChoice choice;
  const int most = all_contenders ? kMaxRefinedCandidates : 1;
  int refined = 0;
  for (const Candidate& c : vote.candidates) {
    if (refined == most) break;
    const bool structural =
        all_contenders && (c.source == CandidateSource::kPrior || c.source == CandidateSource::kIdentity);
    if (c.verified.inliers < kRefineFraction * vote.best_verified && !structural) continue;
    const RefinedRotation r = refineRotation(matches, c.verified, threshold, iterations);
    if (refined++ == 0) {
      choice.winner = r;
      choice.contenders.push_back(r);
      choice.from = &c;
    } else if (choice.challenge(r)) {
      choice.from = &c;
    }
  }
  return choice;
}

// Near structure a wrong rotation with a wrong translation (forward instead of sideways, say) can
// explain the matches almost as well as the right pair, and every voted candidate, each refined
// from the translation its verification sampled, may start in that wrong basin. Translation
// directions change little from frame to frame, so the previous one, with the prior rotation,
// usually starts in the right basin. Not needed when the winner already moves along (or against)
// that direction (under forward driving, every frame).
bool refineFromPreviousMotion(FrameMatches& matches, const Eigen::Matrix3d& prior_rotation,
                              const Eigen::Vector3d& previous_translation, double threshold, int iterations,
                              RefinementChoice* choice) {
  const RefinedRotation& winner = choice->winner;
  const bool same_direction =
      isGeneralMotion(winner) &&
      std::abs(winner.translation.normalized().dot(previous_translation)) > std::cos(kSameTranslationDeg * kDeg);
  if (same_direction) return false;
  return choice->challenge(refineMotion(matches, prior_rotation, previous_translation, threshold, iterations));
}

// Candidates that start on the wrong side of the valley converge to its nearest local minimum, a
// fraction of a degree to a few degrees from the right one. Under forward motion with the matches
// explained there is no such valley and nothing runs.
bool searchValley(FrameMatches& matches, const Eigen::Vector3d& view, int best_verified, double threshold,
                  int iterations, uint64_t seed, RefinementChoice* choice, bool* moved) {
  *moved = false;
  const RefinedRotation& winner = choice->winner;
  if (!isGeneralMotion(winner)) return false;
  const std::vector<Eigen::Vector3d> axes = valleyAxes(winner, view, best_verified);
  if (axes.empty()) return false;
  ValleySteps steps(matches, winner, threshold, seed);
  for (const Eigen::Vector3d& axis : axes) steps.searchAxis(axis);
  if (steps.best() != nullptr) *moved = choice->challenge(refineRotation(matches, *steps.best(), threshold, iterations));
  return true;
}

// At large motion near structure (pairs several frames apart, a prior degrees off) every voted
// rotation can be biased alike by the translation, every candidate start in one wrong basin (a
// forward translation with a rotation degrees off, say): the winner then explains clearly fewer
// matches than the right motion would, with a covariance as tight as a right one's. With many
// wrong matches near structure the winner can also be a wrong basin a degree or two from the
// right rotation, too far for any translation to bring the right matches within the gate, while a
// contender sits in the right basin and lost only through its translation; so the contenders'
// rotations are starts too. Frames whose matches are mostly explained by a well-determined
// translation never run this, nor frames that a pure rotation won.
bool restartFromTranslations(FrameMatches& matches, double threshold, int iterations, RefinementChoice* choice) {
  if (!generalWinnerExplainsTooFew(matches, choice->winner) && !generalWinnerTranslationIsWeak(choice->winner))
    return false;
  std::array<Eigen::Matrix3d, 1 + kRestartContenders> starts;
  starts[0] = choice->winner.rotation;
  size_t start_count = 1;
  const auto elsewhere = [&](const Eigen::Matrix3d& rotation) {
    for (size_t k = 0; k < start_count; ++k)
      if (rotationAngleBetween(starts[k], rotation) < kRestartSeparationDeg * kDeg) return false;
    return true;
  };
  while (start_count < starts.size()) {
    const RefinedRotation* best = nullptr;
    for (const RefinedRotation& c : choice->contenders)
      if ((best == nullptr || c.inliers > best->inliers) && elsewhere(c.rotation)) best = &c;
    if (best == nullptr) break;
    starts[start_count++] = best->rotation;
  }
  bool won = false;
  for (size_t k = 0; k < start_count; ++k)
    for (const Eigen::Vector3d& direction : restartDirections())
      won = choice->challenge(refineMotion(matches, starts[k], direction, threshold, iterations)) || won;
  return won;
}

// Every refinement minimises a Tukey cost under an adaptive gate; with many matches unexplained
// that cost has local minima where it stops 0.1-0.7 deg short of the truncated cost's minimum (the
// criterion that chooses between refinements), with the right translation already. Small steps on
// the truncated cost cross them; a refinement from where they end gives a stationary point, and
// its covariance.
bool descendTruncatedCost(FrameMatches& matches, double threshold, int iterations, RefinementChoice* choice) {
  const RefinedRotation& winner = choice->winner;
  if (!generalWinnerExplainsTooFew(matches, winner)) return false;
  Eigen::Matrix3d rotation = winner.rotation;
  Eigen::Vector3d translation = winner.translation;
  double cost = fittedTranslationCost(matches, rotation, &translation, threshold, kValleyRefits);
  bool moved = false;
  for (const double step_deg : kDescentStepsDeg)
    for (int move = 0; move < kDescentMovesPerStep; ++move) {
      if (!descentMove(matches, threshold, step_deg, &cost, &rotation, &translation)) break;
      moved = true;
    }
  return moved && choice->challenge(refineMotion(matches, rotation, translation, threshold, iterations));
}

// A translation's two parameters fitted to noisy matches leave the rotation loose along the
// rotation/translation valley, the looser the noisier they are: where the general fit's residual
// spread reaches the gate (dim, blurred hand-held rooms; an object moving through the view, which
// the translation takes in as parallax), its rotation was 0.19 deg off (RMSE) on a hand-held room
// of some 600 noisy matches a pair, where the pure rotation was 0.14 deg off. A pure rotation that
// keeps most of the general motion's inliers within its gate shows that the parallax it leaves
// unmodelled is small against the gate, which bounds the bias it takes; near structure it keeps
// fewer, and the general motion stays. A count of inliers does not tell such pairs: the rooms'
// general-motion pairs rest on 12 to 650.
bool preferPureOnWeakSupport(FrameMatches& matches, const CandidateVote& vote, double threshold, int iterations,
                             RefinementChoice* choice) {
  const RefinedRotation& winner = choice->winner;
  if (!isGeneralMotion(winner)) return false;
  if (!(kGateSigmas * winner.residual_sigma >= threshold)) return false;
  VerifiedRotation start;  // no translation: a pure-rotation refinement
  start.rotation = winner.rotation;
  RefinedRotation best = refineRotation(matches, start, threshold, iterations);
  for (size_t k = 0; k < vote.candidates.size() && k < static_cast<size_t>(kMaxRefinedCandidates); ++k) {
    start.rotation = vote.candidates[k].verified.rotation;
    RefinedRotation pure = refineRotation(matches, start, threshold, iterations);
    if (pure.truncated_cost < best.truncated_cost) best = std::move(pure);
  }
  if (!(best.inliers > kPureKeepsShare * winner.inliers)) return false;
  choice->contenders.push_back(best);
  choice->winner = std::move(best);
  return true;
}

// The skew models what a rolling shutter does while the rate changes within the pair, not all of
// it (the rows' translation near structure stays out), and the rigid fit explains the same
// matches: neither excludes the other, so each is a contender of the other.
bool addRowSkew(FrameMatches& matches, double threshold, bool confirmed, RefinementChoice* choice) {
  RefinedRotation skewed = choice->winner;
  if (!fitRowSkew(matches, &skewed, threshold)) return false;
  choice->contenders.push_back(skewed);
  if (confirmed) choice->winner = skewed;
  return true;
}

// A pure rotation absorbs the mean parallax of a translation into its rotation, and its residuals
// keep only the parallax's spread over depths, so neither its fit nor its jackknives show the
// bias. A general fit from it does, when the matches determine a translation; a lateral one moves
// the image as a rotation across the view does, which is the bias to bound, and the forward
// direction adds nothing there.
Eigen::Vector3d translationOffset(FrameMatches& matches, const RefinedRotation& winner, double threshold,
                                  int iterations) {
  if (!winner.pure_rotation) return Eigen::Vector3d::Zero();
  RefinedRotation best;
  for (const Eigen::Vector3d lateral : {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY()}) {
    const RefinedRotation general = refineMotion(matches, winner.rotation, lateral, threshold, iterations);
    if (best.inliers == 0 || general.truncated_cost < best.truncated_cost) best = general;
  }
  if (best.inliers == 0) return Eigen::Vector3d::Zero();
  return so3Log(winner.rotation.transpose() * best.rotation);
}

}  // namespace visual_gyro
