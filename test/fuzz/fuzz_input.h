// What the libFuzzer targets of the estimator and the pipeline share: reading numbers from the
// fuzzer's bytes, and the checks every valid estimate must pass.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include <Eigen/Dense>

namespace visual_gyro {
namespace fuzz {

/// Reads the input front to back; past its end every read gives zero.
class Bytes {
 public:
  Bytes(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  uint8_t byte() { return at_ < size_ ? data_[at_++] : 0; }
  /// The next four bytes as a float (any value: NaN, infinities, denormals).
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

/// Aborts, so that the fuzzer keeps the input, saying what failed.
inline void check(bool ok, const char* what) {
  if (ok) return;
  std::fprintf(stderr, "fuzz check failed: %s\n", what);
  std::abort();
}

/// A covariance must be finite, exactly symmetric and positive semi-definite.
inline void checkCovariance(const Eigen::Matrix3d& c) {
  check(c.allFinite(), "a non-finite covariance");
  check(c == c.transpose(), "an asymmetric covariance");
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(c);
  check(eigen.eigenvalues().minCoeff() >= -1e-12 * (1.0 + eigen.eigenvalues().maxCoeff()),
        "a covariance that is not positive semi-definite");
}

/// A valid estimate's rotation must be a finite proper rotation.
inline void checkRotation(const Eigen::Matrix3d& r) {
  check(r.allFinite(), "a non-finite rotation");
  check((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() < 1e-6 && r.determinant() > 0.0,
        "an estimate that is no proper rotation");
}

}  // namespace fuzz
}  // namespace visual_gyro
