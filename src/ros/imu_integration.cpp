#include "imu_integration.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Geometry>

#include "visual_gyro/geometry.h"

namespace visual_gyro {
namespace imu_integration {

namespace {

/// Truth at t (clamped to the samples' span), slerp between neighbours.
Eigen::Quaterniond truthAt(const std::vector<TruthSample>& truth, double t) {
  auto it = std::lower_bound(truth.begin(), truth.end(), t,
                             [](const TruthSample& s, double v) { return s.stamp < v; });
  if (it == truth.begin()) return Eigen::Quaterniond(truth.front().orientation);
  if (it == truth.end()) return Eigen::Quaterniond(truth.back().orientation);
  const TruthSample& b = *it;
  const TruthSample& a = *(it - 1);
  const double u = (t - a.stamp) / (b.stamp - a.stamp);
  return Eigen::Quaterniond(a.orientation).slerp(u, Eigen::Quaterniond(b.orientation));
}

}  // namespace

IntegrationError integrationError(const std::vector<RateSample>& rates, const std::vector<TruthSample>& truth,
                                  double step) {
  if (truth.size() < 2) throw std::invalid_argument("integrationError needs at least two truth samples");
  if (!(step > 0.0)) throw std::invalid_argument("integrationError needs a positive step");
  const double t0 = truth.front().stamp, t_end = truth.back().stamp;
  const Eigen::Matrix3d reference_t = truth.front().orientation.transpose();

  IntegrationError out;
  Eigen::Matrix3d integrated = Eigen::Matrix3d::Identity();
  double t_integrated = t0;
  size_t next = 0;  // first rate message not yet in effect
  Eigen::Vector3d rate = Eigen::Vector3d::Zero();
  while (next < rates.size() && rates[next].stamp <= t0) rate = rates[next++].rate;
  // Advances the integration to t, switching rates at each message stamp on the way.
  auto advance = [&](double t) {
    while (next < rates.size() && rates[next].stamp <= t) {
      integrated = integrated * so3Exp(rate * (rates[next].stamp - t_integrated));
      t_integrated = rates[next].stamp;
      rate = rates[next++].rate;
    }
    integrated = integrated * so3Exp(rate * (t - t_integrated));
    t_integrated = t;
  };

  double sum_sq = 0.0, sum = 0.0;
  const int steps = static_cast<int>(std::floor((t_end - t0) / step + 1e-9));
  for (int k = 0; k <= steps; ++k) {
    const double t = t0 + k * step;
    advance(t);
    const Eigen::Matrix3d truth_rel = reference_t * truthAt(truth, t).toRotationMatrix();
    const double error = Eigen::AngleAxisd(integrated.transpose() * truth_rel).angle() * kRadToDeg;
    out.series.push_back({t - t0, error});
    sum_sq += error * error;
    sum += error;
    out.max_deg = std::max(out.max_deg, error);
  }
  const double n = static_cast<double>(out.series.size());
  out.rms_deg = std::sqrt(sum_sq / n);
  out.mean_deg = sum / n;
  out.final_deg = out.series.back().error_deg;
  return out;
}

}  // namespace imu_integration
}  // namespace visual_gyro
