// Candidate rotations of the vote method: the voting passes and the verification of their cells.
#include "vote_candidates.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace visual_gyro {

namespace {

constexpr double kDeg = kDegToRad;

// Cells per axis of the narrow histogram at most (128^3 cells) and of the wide one (40^3): a
// finer rotation_bin_deg is widened to fit its window, so every setting in range is usable.
constexpr double kMaxNarrowBins = 128.0;
constexpr double kMaxWideBins = 40.0;

// The fullest cells, each read as the vote-weighted mean of its 3x3x3 neighbourhood (which
// absorbs the quantisation of the grid).
Eigen::Vector3d cellMean(const VoteResult& votes, const Eigen::Vector3i& ijk, int n) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int count = 0;
  for (int dx = -1; dx <= 1; ++dx)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dz = -1; dz <= 1; ++dz) {
        const Eigen::Vector3i q = ijk + Eigen::Vector3i(dx, dy, dz);
        if ((q.array() < 0).any() || (q.array() >= n).any()) continue;
        const int qc = (q.x() * n + q.y()) * n + q.z();
        count += votes.histogram[qc];
        sum += Eigen::Vector3d(votes.cell_sums[3 * qc], votes.cell_sums[3 * qc + 1], votes.cell_sums[3 * qc + 2]);
      }
  return sum / count;
}

// The voted cells, fullest first (ties by index), at most `keep` of them. Found a block at a
// time: most blocks of a wide histogram hold no vote, and one vectorised test passes over a block.
std::vector<int> fullestCells(const VoteResult& votes, int keep) {
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
  keep = std::min<int>(static_cast<int>(order.size()), keep);
  std::partial_sort(order.begin(), order.begin() + keep, order.end(), [&](int a, int b) {
    return histogram[a] != histogram[b] ? histogram[a] > histogram[b] : a < b;
  });
  order.resize(keep);
  return order;
}

// The `wanted` fullest cells that are distinct modes: a cell adjacent to one already chosen is
// skipped. Each is read as its neighbourhood's mean rotation vector [rad].
std::vector<Eigen::Vector3d> topCells(const VoteResult& votes, const hyp::VoteGrid& grid, int wanted) {
  const int n = grid.bins;
  std::vector<Eigen::Vector3d> out;
  std::vector<Eigen::Vector3i> chosen;
  for (int cell : fullestCells(votes, 8 * wanted)) {
    const Eigen::Vector3i ijk(cell / (n * n), (cell / n) % n, cell % n);
    bool near = false;
    for (const auto& c : chosen) near = near || (c - ijk).cwiseAbs().maxCoeff() <= 1;
    if (near) continue;
    out.push_back(cellMean(votes, ijk, n));
    chosen.push_back(ijk);
    if (static_cast<int>(out.size()) == wanted) break;
  }
  return out;
}

// Verifies candidates and keeps the distinct ones.
class CandidateList {
 public:
  CandidateList(const CandidateVoteInput& input, CandidateVote* vote) : input_(input), vote_(vote) {}

  void consider(const Eigen::Vector3d& rotation_vector, CandidateSource source) {
    // Candidates within half a cell of one already verified would verify to the same inliers.
    for (const Candidate& c : vote_->candidates)
      if ((c.rotation_vector - rotation_vector).norm() < 0.5 * input_.settings->rotation_bin_deg * kDeg) return;
    // Voted candidates are off by a few tenths of a degree under translation: a looser gate lets
    // them gather the inliers (and the epipole) that refinement then tightens.
    Candidate c;
    c.rotation_vector = rotation_vector;
    c.source = source;
    c.verified = verifyRotation(*input_.matches, so3Exp(rotation_vector),
                                2.0 * input_.settings->inlier_threshold_deg * kDeg, input_.seed);
    if (c.verified.inliers > vote_->best_verified) {
      vote_->best_verified = c.verified.inliers;
      best_is_prior_ = source == CandidateSource::kPrior;
    }
    vote_->candidates.push_back(c);
  }
  bool bestIsPrior() const { return best_is_prior_; }

 private:
  const CandidateVoteInput& input_;
  CandidateVote* vote_;
  bool best_is_prior_ = false;
};

// One vote: narrow (around `centre`, with the angle-change test) or wide (about zero, every
// non-degenerate triple); its counts added to *vote.
VoteRequest voteOnce(const CandidateVoteInput& input, bool narrow, const CastVotes& cast, VoteResult* votes,
                     CandidateVote* vote) {
  const EstimatorSettings& s = *input.settings;
  const Eigen::Vector3d centre = narrow && input.prior != nullptr ? *input.prior : Eigen::Vector3d::Zero();
  const double window = narrow ? s.rotation_window_deg : s.wide_window_deg;
  const double bin = std::max(s.rotation_bin_deg, 2.0 * window / (narrow ? kMaxNarrowBins : kMaxWideBins));
  VoteRequest request;
  request.prev = input.prev->data();
  request.cur = input.cur->data();
  request.matches = static_cast<uint32_t>(input.prev->size());
  request.hypotheses = static_cast<uint32_t>(s.hypotheses);
  request.seed = input.seed + (narrow ? 0 : 0x9E3779B97F4A7C15ull);
  request.grid.kind = hyp::kVoteRotationVector;
  for (int k = 0; k < 3; ++k) request.grid.centre[k] = static_cast<float>(centre[k]);
  request.grid.bin_width = static_cast<float>(bin * kDeg);
  request.grid.bins = binsFor(window, bin);
  request.triple = tripleOptions(s, false, narrow ? s.max_angle_change_deg : 0.0);
  cast(request, votes);
  vote->hypotheses_drawn += s.hypotheses;
  vote->hypotheses_accepted += static_cast<int>(votes->accepted);
  const int winning = votes->winner >= 0 ? votes->histogram[votes->winner] : 0;
  vote->winning_votes = std::max(vote->winning_votes, winning);
  return request;
}

}  // namespace

const char* candidateSourceName(CandidateSource source) {
  switch (source) {
    case CandidateSource::kNarrow: return "narrow";
    case CandidateSource::kWide: return "wide";
    case CandidateSource::kPrior: return "prior";
    case CandidateSource::kIdentity: return "identity";
  }
  return "";
}

CandidateVote voteCandidates(const CandidateVoteInput& input, const CastVotes& cast, VoteResult* votes) {
  const EstimatorSettings& s = *input.settings;
  CandidateVote vote;
  CandidateList list(input, &vote);
  for (const bool narrow : {true, false}) {
    const VoteRequest request = voteOnce(input, narrow, cast, votes, &vote);
    vote.wide_vote = vote.wide_vote || !narrow;
    const CandidateSource source = narrow ? CandidateSource::kNarrow : CandidateSource::kWide;
    for (const Eigen::Vector3d& c : topCells(*votes, request.grid, s.candidates)) list.consider(c, source);
    // The prior, and no rotation at all, are candidates too: under strong translation every
    // rotation-only triple is biased, and the truth is usually closer to one of them.
    if (narrow && input.prior != nullptr && input.prior_candidate) list.consider(*input.prior, CandidateSource::kPrior);
    if (narrow && input.identity_candidate) list.consider(Eigen::Vector3d::Zero(), CandidateSource::kIdentity);
    const bool prior_unchallenged = input.prior != nullptr && list.bestIsPrior();
    if (vote.best_verified >= input.needed && vote.winning_votes >= s.min_votes && !prior_unchallenged) break;
    if (!input.wide_vote) break;
  }
  std::stable_sort(vote.candidates.begin(), vote.candidates.end(),
                   [](const Candidate& a, const Candidate& b) { return a.verified.inliers > b.verified.inliers; });
  return vote;
}

hyp::TripleOptions tripleOptions(const EstimatorSettings& s, bool centroid, double max_change_deg) {
  hyp::TripleOptions opt;
  opt.centroid_subtraction = centroid ? 1 : 0;
  opt.min_separation = static_cast<float>(2.0 * std::sin(0.5 * s.min_separation_deg * kDeg));
  opt.min_triangle_area = static_cast<float>(s.min_triangle_area_deg2 * kDeg * kDeg);
  opt.max_angle_change = static_cast<float>(max_change_deg * kDeg);
  return opt;
}

int binsFor(double window_deg, double bin_deg) {
  const double bins = std::ceil(2.0 * window_deg / bin_deg - 1e-9);
  // Saturate before converting: a double beyond int's range (a tiny bin) would be undefined
  // behaviour, and NaN must not pass as a small histogram.
  if (!(bins < static_cast<double>(std::numeric_limits<int>::max()))) return std::numeric_limits<int>::max();
  return std::max(1, static_cast<int>(bins));
}

}  // namespace visual_gyro
