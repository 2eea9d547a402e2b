// Whether the camera model fits the images: correlation of neighbouring matches' residuals.
#include "visual_gyro/calibration_fit.h"
#include "visual_gyro/geometry.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <Eigen/Geometry>

namespace visual_gyro {

namespace {

/// Key of the grid cell (side `cell` in unit-sphere coordinates) holding bearing `b`.
long long cellKey(const Eigen::Vector3d& b, double cell) {
  // Unit vectors span [-1, 1]: at most 2 / cell + 1 cells per axis, far below 2^20 for any cell
  // of a pixel-sized angle.
  constexpr long long kSpan = 1 << 20;
  const long long x = static_cast<long long>(std::floor((b.x() + 1.0) / cell));
  const long long y = static_cast<long long>(std::floor((b.y() + 1.0) / cell));
  const long long z = static_cast<long long>(std::floor((b.z() + 1.0) / cell));
  return (x * kSpan + y) * kSpan + z;
}

}  // namespace

Eigen::Vector3d motionResidual(const Eigen::Vector3d& previous, const Eigen::Vector3d& current,
                               const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation,
                               const Eigen::Vector3d& row_skew) {
  const Eigen::Vector3d predicted =
      row_skew.isZero() ? Eigen::Vector3d(rotation * current)
                        : Eigen::Vector3d(rotation * so3Exp(matchRow(previous, current) * row_skew) * current);
  if (translation.squaredNorm() < 0.25) return previous - predicted;
  // Along the epipolar line the residual is parallax (depth), which neighbours share without any
  // calibration error; only the distance from the epipolar plane is the model's error.
  Eigen::Vector3d normal = translation.cross(predicted);
  const double length = normal.norm();
  if (!(length > 1e-9)) return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  normal /= length;
  return previous.dot(normal) * normal;
}

double ResidualCorrelation::compute(const std::vector<Eigen::Vector3d>& previous,
                                    const std::vector<Eigen::Vector3d>& current, const Eigen::Matrix3d& rotation,
                                    const Eigen::Vector3d& translation, double pixel_angle_rad, double gate_rad,
                                    const Eigen::Vector3d& row_skew) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (previous.size() != current.size() || !(pixel_angle_rad > 0.0) || !(gate_rad > 0.0)) return nan;
  // Chords instead of angles: equal to well below a pixel at these separations.
  const double min_chord = kFitMinSeparationPx * pixel_angle_rad;
  const double max_chord = kFitMaxSeparationPx * pixel_angle_rad;
  const double max_residual = kFitResidualGates * gate_rad;
  points_.clear();
  // At most kFitMaxMatches, evenly spread over the match list: enough for the correlation (its
  // standard error is about 1 / sqrt(pairs)), and the search stays a fraction of a millisecond.
  const size_t stride = std::max<size_t>(1, (previous.size() + kFitMaxMatches - 1) / kFitMaxMatches);
  for (size_t i = 0; i < previous.size(); i += stride) {
    const Eigen::Vector3d r = motionResidual(previous[i], current[i], rotation, translation, row_skew);
    if (!r.allFinite() || !current[i].allFinite() || r.norm() > max_residual) continue;
    points_.push_back(Point{cellKey(current[i], max_chord), current[i], r});
  }
  std::sort(points_.begin(), points_.end(), [](const Point& a, const Point& b) { return a.cell < b.cell; });
  const auto byCell = [](const Point& p, long long key) { return p.cell < key; };
  constexpr long long kSpan = 1 << 20;
  double cross = 0.0, first = 0.0, second = 0.0;
  int pairs = 0;
  for (const Point& p : points_) {
    const Point* nearest = nullptr;
    double best = max_chord * max_chord;
    // The neighbour lies within one cell along each axis: 27 cells.
    for (long long dx = -1; dx <= 1; ++dx) {
      for (long long dy = -1; dy <= 1; ++dy) {
        for (long long dz = -1; dz <= 1; ++dz) {
          const long long key = p.cell + (dx * kSpan + dy) * kSpan + dz;
          for (auto it = std::lower_bound(points_.begin(), points_.end(), key, byCell);
               it != points_.end() && it->cell == key; ++it) {
            const double d2 = (it->bearing - p.bearing).squaredNorm();
            if (d2 >= min_chord * min_chord && d2 <= best) {
              best = d2;
              nearest = &*it;
            }
          }
        }
      }
    }
    if (nearest == nullptr) continue;
    cross += p.residual.dot(nearest->residual);
    first += p.residual.squaredNorm();
    second += nearest->residual.squaredNorm();
    ++pairs;
  }
  if (pairs < kFitMinPairs || !(first > 0.0) || !(second > 0.0)) return nan;
  return cross / std::sqrt(first * second);
}

void CalibrationFitMonitor::add(double correlation) {
  if (!std::isfinite(correlation)) return;
  if (window_.size() == kFitWindowFrames) window_.erase(window_.begin());
  window_.push_back(correlation);
}

bool CalibrationFitMonitor::mismatch() const {
  return window_.size() == kFitWindowFrames && median() >= kFitMismatchCorrelation;
}

double CalibrationFitMonitor::median() const {
  if (window_.empty()) return std::numeric_limits<double>::quiet_NaN();
  sorted_.assign(window_.begin(), window_.end());
  const auto mid = sorted_.begin() + static_cast<std::ptrdiff_t>(sorted_.size() / 2);
  std::nth_element(sorted_.begin(), mid, sorted_.end());
  return *mid;
}

double CalibrationFitMonitor::covarianceInflation() const {
  if (!mismatch()) return 1.0;
  const double rho = median();
  return std::min(kMaxFitInflation, (1.0 + rho) / std::max(1e-9, 1.0 - rho));
}

std::string CalibrationFitMonitor::describe() const {
  const double rho = median();
  // Residual = shared part + independent part; their correlation rho is the shared part's share
  // of the variance, so the shared (systematic) error is sqrt(rho / (1 - rho)) times the noise.
  const double ratio = std::sqrt(std::max(0.0, rho) / std::max(1e-6, 1.0 - rho));
  std::ostringstream out;
  out.precision(2);
  out << "residuals of neighbouring matches agree (correlation " << rho << " over the last " << window_.size()
      << " frames; " << kFitMismatchCorrelation
      << " and more is not pixel noise): a systematic error " << ratio
      << " times the pixel noise; camera_info's distortion or intrinsics may not fit the images (or a rolling "
         "shutter distorts them); covariance times "
      << covarianceInflation();
  return out.str();
}

}  // namespace visual_gyro
