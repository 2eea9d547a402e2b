// libFuzzer target: the rotation estimator (vote and paper, CPU voter) on bearing lists that come
// from the fuzzer: repeated, coincident, antipodal, coplanar or nearly parallel bearings, lists of
// unequal length, non-unit and non-finite vectors. Bad input must give an invalid result with a
// reason, never a crash, a hang or a sanitizer report; a valid result must be a finite proper
// rotation with a finite, symmetric, positive semi-definite covariance.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <vector>

#include <Eigen/Dense>

#include "visual_gyro/geometry.h"
#include "visual_gyro/rotation_estimator.h"

namespace vg = visual_gyro;

namespace {

// Reads the input front to back; past its end every read gives zero.
class Bytes {
 public:
  Bytes(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  uint8_t byte() { return at_ < size_ ? data_[at_++] : 0; }
  float number() {
    uint8_t raw[sizeof(float)] = {};
    for (uint8_t& b : raw) b = byte();
    float value;
    std::memcpy(&value, raw, sizeof(value));
    return value;
  }
  bool done() const { return at_ >= size_; }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t at_ = 0;
};

// A bearing from the input: raw, or normalised so that most inputs pass the estimator's checks and
// reach the voting, the refinement and the covariance; a third of them copy an earlier bearing
// (repeated and coincident points).
Eigen::Vector3d bearing(Bytes& in, bool normalise, const std::vector<Eigen::Vector3d>& earlier) {
  const uint8_t kind = in.byte();
  if (kind % 3 == 0 && !earlier.empty()) return earlier[kind % earlier.size()];
  Eigen::Vector3d b(in.number(), in.number(), in.number());
  if (normalise && b.allFinite() && b.norm() > 1e-30) b.normalize();
  return b;
}

// Aborts (the fuzzer then keeps the input) with what failed.
void check(bool ok, const char* what) {
  if (ok) return;
  std::fprintf(stderr, "fuzz_estimator: %s\n", what);
  std::abort();
}

void checkResult(const vg::RotationResult& r) {
  if (!r.valid()) {
    check(!r.reason.empty(), "an invalid result without a reason");
    return;
  }
  check(r.rotation.allFinite() && r.covariance.allFinite() && r.rotation_vector.allFinite(), "a valid result with a non-finite rotation or covariance");
  check((r.rotation.transpose() * r.rotation - Eigen::Matrix3d::Identity()).norm() < 1e-6, "a valid rotation that is not orthonormal");
  check(r.rotation.determinant() > 0.0, "a valid rotation that is a reflection");
  check((r.covariance - r.covariance.transpose()).norm() <= 1e-9 * (1.0 + r.covariance.norm()), "an asymmetric covariance");
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(0.5 * (r.covariance + r.covariance.transpose()));
  check(eigen.eigenvalues().minCoeff() >= -1e-12 * (1.0 + eigen.eigenvalues().maxCoeff()), "a covariance that is not positive semi-definite");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Bytes in(data, size);
  const uint8_t options = in.byte();
  vg::EstimatorSettings settings;
  settings.method = options & 1 ? vg::EstimationMethod::kPaper : vg::EstimationMethod::kVote;
  settings.backend = vg::BackendChoice::kCpu;
  settings.hypotheses = 64 + in.byte() * 4;  // enough triples to vote, few enough to stay fast
  settings.use_prior = (options & 2) != 0;
  const bool normalise = (options & 4) == 0;
  const bool unequal = (options & 8) != 0;
  std::unique_ptr<vg::RotationEstimator> estimator = vg::createRotationEstimator(settings, nullptr);
  estimator->setRefinedPositions((options & 16) != 0);
  vg::PriorTracker prior;
  // Up to three frames from one input, so that the prior, the row skew's window and the scratch
  // reused between frames are exercised too.
  for (int frame = 0; frame < 3 && !in.done(); ++frame) {
    const size_t matches = in.byte() + (in.byte() & 3) * 256;  // 0..1023
    std::vector<Eigen::Vector3d> previous, current;
    // A structured frame: the current bearings the previous ones turned by a rotation of up to
    // ~10 deg, each moved by a small amount from the input (noise, parallax, wrong matches), so
    // that the vote finds a rotation and every later stage runs.
    const bool structured = (options & 32) != 0;
    const Eigen::Matrix3d turn =
        vg::so3Exp(Eigen::Vector3d(in.byte() - 128.0, in.byte() - 128.0, in.byte() - 128.0) * 1.4e-3);
    for (size_t i = 0; i < matches && !in.done(); ++i) {
      previous.push_back(bearing(in, normalise, previous));
      if (structured) {
        const uint8_t shift = in.byte();
        const Eigen::Vector3d moved = turn.transpose() * previous.back() +
                                      (shift < 160 ? 1e-4 : 2e-2) * Eigen::Vector3d(in.byte() - 128.0, in.byte() - 128.0, 0.0) / 128.0;
        current.push_back(normalise && moved.allFinite() && moved.norm() > 1e-30 ? moved.normalized() : moved);
      } else {
        current.push_back(bearing(in, normalise, current));
      }
    }
    if (unequal && !current.empty()) current.pop_back();
    const vg::RotationResult r = estimator->estimate(previous, current, prior.priorFor(1.0 / 30.0));
    checkResult(r);
    prior.update(r, 1.0 / 30.0);
  }
  return 0;
}
