// libFuzzer target: the rotation estimator (vote and paper, CPU voter) on bearing lists that come
// from the fuzzer: repeated, coincident, antipodal, coplanar or nearly parallel bearings, lists of
// unequal length, non-unit and non-finite vectors. Bad input must give an invalid result with a
// reason, never a crash, a hang or a sanitizer report; a valid result must be a finite proper
// rotation with a finite, exactly symmetric, positive semi-definite covariance.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Dense>

#include "visual_gyro/geometry.h"
#include "visual_gyro/rotation_estimator.h"
#include "fuzz_input.h"

namespace vg = visual_gyro;
using namespace vg::fuzz;  // the targets' input reader and checks

namespace {

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

void checkResult(const vg::RotationResult& r) {
  if (!r.valid()) {
    check(!r.reason.empty(), "an invalid result without a reason");
    return;
  }
  checkRotation(r.rotation);
  check(r.rotation_vector.allFinite(), "a non-finite rotation vector");
  checkCovariance(r.covariance);
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
        const double reach = in.byte() < 160 ? 1e-4 : 2e-2;  // noise, or a wrong match
        const Eigen::Vector3d offset(in.byte() - 128.0, in.byte() - 128.0, 0.0);
        const Eigen::Vector3d moved = turn.transpose() * previous.back() + reach * offset / 128.0;
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
