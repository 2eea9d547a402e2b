// The backend interface of the voting RANSAC: draw, solve and vote hypotheses for one frame.
// Eigen- and OpenCV-free so that the CUDA backend (cuda/) and its stand-alone test and benchmark
// build with nvcc and CMake alone.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "hypothesis_math.h"

namespace visual_gyro {

/// One frame's voting job. Bearings are unit vectors, prev[i] <-> cur[i] one match.
struct VoteRequest {
  const hyp::Vec3f* prev = nullptr;  ///< bearings in frame k-1 (n of them)
  const hyp::Vec3f* cur = nullptr;   ///< bearings in frame k (n of them)
  uint32_t matches = 0;              ///< n; must be >= 3
  uint32_t hypotheses = 0;           ///< number of triples to draw
  uint64_t seed = 0;                 ///< Philox key: same seed -> same triples on every backend
  hyp::TripleOptions triple{};       ///< degeneracy and consistency tests
  hyp::VoteGrid grid{};              ///< histogram the hypotheses vote into
  bool keep_records = false;         ///< fill VoteResult::records (one per hypothesis)
};

/// What a backend returns for a VoteRequest.
struct VoteResult {
  std::vector<int32_t> histogram;             ///< votes per cell (hyp::cellCount(grid) cells)
  std::vector<float> cell_sums;               ///< per cell, sums of HypothesisRecord::value (3 each)
  std::vector<hyp::HypothesisRecord> records;  ///< per hypothesis, when keep_records
  int32_t winner = -1;                        ///< fullest cell (lowest index on ties), -1 if none
  uint32_t accepted = 0;                      ///< hypotheses that voted (inside the window)
  uint32_t rejected[6] = {0, 0, 0, 0, 0, 0};  ///< counts per hyp::TripleStatus
  double device_ms = 0.0;                     ///< kernel time when the backend measures it [ms]
};

/// A hypothesis-voting backend (CPU or CUDA). Implementations throw std::runtime_error on
/// failure; they never terminate the process.
class HypothesisVoter {
 public:
  virtual ~HypothesisVoter() = default;
  /// Runs one frame's voting. Throws std::invalid_argument on a malformed request.
  virtual void vote(const VoteRequest& request, VoteResult* result) = 0;
  /// "cpu" or "cuda".
  virtual std::string name() const = 0;
};

/// The reference CPU voter (single thread; the gold implementation the GPU is checked against).
std::unique_ptr<HypothesisVoter> createCpuVoter();

/// Checks a request; throws std::invalid_argument naming the problem.
void validateVoteRequest(const VoteRequest& request);

}  // namespace visual_gyro
