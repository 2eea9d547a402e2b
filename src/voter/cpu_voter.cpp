// The reference CPU voter: the gold implementation the CUDA backend is checked against bin for bin.
// Deliberately free of Eigen and OpenCV so that cuda/'s stand-alone build (nvcc + CMake only) can
// compile it next to the kernels.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "hypothesis_voter.h"
#include "triple_batch.h"

namespace visual_gyro {

void validateVoteRequest(const VoteRequest& request) {
  if (request.prev == nullptr || request.cur == nullptr)
    throw std::invalid_argument("vote request without bearings");
  if (request.matches < 3)
    throw std::invalid_argument("vote request needs at least 3 matches, got " +
                                std::to_string(request.matches));
  const hyp::VoteGrid& g = request.grid;
  if (g.kind != hyp::kVoteYaw && g.kind != hyp::kVoteRotationVector)
    throw std::invalid_argument("vote grid of unknown kind " + std::to_string(g.kind));
  if (!(g.bin_width > 0.f) || !std::isfinite(g.bin_width))
    throw std::invalid_argument("vote grid bin width must be positive");
  // 256^3 cells (64 MiB of counters) is far beyond any useful rotation grid: a larger one is a bug.
  const int32_t max_bins = g.kind == hyp::kVoteYaw ? (1 << 22) : 256;
  if (g.bins < 1 || g.bins > max_bins)
    throw std::invalid_argument("vote grid needs 1.." + std::to_string(max_bins) + " bins, got " +
                                std::to_string(g.bins));
  for (float c : g.centre)
    if (!std::isfinite(c)) throw std::invalid_argument("vote grid centre is not finite");
}

namespace {

class CpuVoter : public HypothesisVoter {
 public:
  void vote(const VoteRequest& request, VoteResult* result) override {
    validateVoteRequest(request);
    const int32_t cells = hyp::cellCount(request.grid);
    result->histogram.assign(cells, 0);
    result->cell_sums.assign(static_cast<size_t>(cells) * 3, 0.f);
    result->records.clear();
    if (request.keep_records) result->records.resize(request.hypotheses);
    result->accepted = 0;
    for (uint32_t& r : result->rejected) r = 0;
    result->device_ms = 0.0;

    // The hypotheses are drawn and solved a chunk at a time (in SIMD lanes where the CPU can, the
    // same rotations as one at a time) and binned in their order, so the per-cell sums add up in
    // the same order either way.
    constexpr int kChunk = 128;
    uint32_t triples[kChunk][3];
    int32_t solved[kChunk];
    hyp::Mat3f rotations[kChunk];
    hyp::HypothesisRecord record;
    // The winner is kept up to date vote by vote (no pass over the cells): the fullest cell, the
    // lowest index among equally full ones.
    result->winner = -1;
    int32_t best = 0;
    for (uint32_t first = 0; first < request.hypotheses; first += kChunk) {
      const int count = static_cast<int>(std::min<uint32_t>(kChunk, request.hypotheses - first));
      hyp::drawTriples(request.seed, first, count, request.matches, triples);
      hyp::solveTriples(request.prev, request.cur, triples, count, request.triple, solved, rotations);
      for (int k = 0; k < count; ++k) {
        const uint32_t h = first + k;
        const int32_t status = hyp::binHypothesis(solved[k], rotations[k], request.grid, &record);
        if (request.keep_records) result->records[h] = record;
        if (status != hyp::kTripleOk) {
          ++result->rejected[status];
          continue;
        }
        ++result->accepted;
        const int32_t votes = ++result->histogram[record.cell];
        if (votes > best || (votes == best && record.cell < result->winner)) {
          best = votes;
          result->winner = record.cell;
        }
        float* sum = &result->cell_sums[static_cast<size_t>(record.cell) * 3];
        sum[0] += record.value[0];
        sum[1] += record.value[1];
        sum[2] += record.value[2];
      }
    }
  }

  std::string name() const override { return "cpu"; }
};

}  // namespace

std::unique_ptr<HypothesisVoter> createCpuVoter() { return std::make_unique<CpuVoter>(); }

}  // namespace visual_gyro
