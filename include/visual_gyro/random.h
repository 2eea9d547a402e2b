// The package's one deterministic random generator: splitmix64 (Steele, Lea, Flood 2014). Tiny,
// well mixed and fully specified, so a seed gives the same numbers with every compiler and
// standard library (the standard distributions do not: their output is implementation-defined).
// Free of Eigen and OpenCV so that the stand-alone CUDA tools can use it too.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <utility>

namespace visual_gyro {

/// splitmix64 with the few distributions the package needs.
class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed = 0) : state_(seed) {}

  /// Next 64 random bits.
  uint64_t next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  /// Uniform in [0, 1) (53 bits).
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  /// Uniform in (0, 1]: safe to take the logarithm of.
  double uniformPositive() { return (static_cast<double>(next() >> 11) + 1.0) * 0x1.0p-53; }
  /// Uniform in [lo, hi).
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  /// Log-uniform in [lo, hi), lo > 0.
  double logUniform(double lo, double hi) { return lo * std::exp(std::log(hi / lo) * uniform()); }
  /// Uniform integer in [0, n), n > 0 (multiply-shift: no modulo bias worth mentioning for n << 2^32).
  uint64_t below(uint64_t n) { return static_cast<uint64_t>((static_cast<unsigned __int128>(next()) * n) >> 64); }
  /// Shuffles a random-access container in place (Fisher-Yates; the same order everywhere).
  template <class Container>
  void shuffle(Container& items) {
    using std::swap;
    for (size_t i = items.size(); i > 1; --i) swap(items[i - 1], items[below(i)]);
  }
  /// Standard normal (Box-Muller; both outputs are used, one per call).
  double normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u1 = uniform();
    while (u1 <= 1e-300) u1 = uniform();
    const double u2 = uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(2.0 * 3.14159265358979323846 * u2);
    has_spare_ = true;
    return r * std::cos(2.0 * 3.14159265358979323846 * u2);
  }

 private:
  uint64_t state_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

}  // namespace visual_gyro
