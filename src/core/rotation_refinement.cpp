#include "rotation_refinement.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace visual_gyro {

namespace {

constexpr double kRotationGateScale = 1.25;

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

Eigen::Matrix3d expMap(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  if (angle < 1e-15) return Eigen::Matrix3d::Identity() + skew(w);
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

// Two unit vectors orthogonal to t: the tangent plane in which t is updated.
Eigen::Matrix<double, 3, 2> tangentBasis(const Eigen::Vector3d& t) {
  const Eigen::Vector3d helper =
      std::abs(t.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  Eigen::Matrix<double, 3, 2> B;
  B.col(0) = t.cross(helper).normalized();
  B.col(1) = t.cross(B.col(0));
  return B;
}

// Row of d(t . (p x R exp(d) c))/d(d, tau): t^T [p]x R (-[c]x) = -((R^T (t x p)) x c)^T for the
// rotation, n^T B for the tangent-plane translation step. Cross products instead of 3x3 matrices:
// this runs for every inlier in every iteration.
Eigen::Matrix<double, 1, 5> epipolarJacobian(const Eigen::Vector3d& p, const Eigen::Vector3d& c,
                                             const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                                             const Eigen::Vector3d& normal,
                                             const Eigen::Matrix<double, 3, 2>& B) {
  Eigen::Matrix<double, 1, 5> J;
  J.head<3>() = -((R.transpose() * t.cross(p)).cross(c)).transpose();
  J.tail<2>() = normal.transpose() * B;
  return J;
}

double huberWeight(double r, double k) {
  const double a = std::abs(r);
  return a <= k ? 1.0 : k / a;
}

// splitmix64: a tiny deterministic generator for the translation RANSAC (reproducible runs).
uint64_t nextRandom(uint64_t* state) {
  uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// Matches whose bearings point into opposite half-spaces after the rotation cannot be one point.
bool sameHemisphere(const Eigen::Vector3d& p, const Eigen::Vector3d& rc) { return p.dot(rc) > 0.0; }

// 3.5 robust sigmas (1.4826 MAD) of the residuals below the threshold, clamped to
// [threshold / 8, threshold]. With t == nullptr the residual is the pure-rotation one |b x R b'|.
double adaptiveGate(const std::vector<Eigen::Vector3d>& previous,
                    const std::vector<Eigen::Vector3d>& current, const Eigen::Matrix3d& R,
                    const Eigen::Vector3d* t, double threshold) {
  std::vector<double> residuals;
  residuals.reserve(previous.size());
  for (size_t i = 0; i < previous.size(); ++i) {
    const Eigen::Vector3d rc = R * current[i];
    if (!sameHemisphere(previous[i], rc)) continue;
    const Eigen::Vector3d normal = previous[i].cross(rc);
    const double r = t != nullptr ? std::abs(t->dot(normal)) : normal.norm();
    if (r < threshold) residuals.push_back(r);
  }
  if (residuals.size() < 10) return threshold;
  const size_t mid = residuals.size() / 2;
  std::nth_element(residuals.begin(), residuals.begin() + mid, residuals.end());
  // The 2-D pure-rotation residual's median is ~1.18 sigma, the 1-D |r|'s 0.67 sigma.
  const double sigma = residuals[mid] / (t != nullptr ? 0.6745 : 1.1774);
  return std::clamp(3.5 * sigma, threshold / 8.0, threshold);
}

RefinedRotation refinePureRotation(const std::vector<Eigen::Vector3d>& previous,
                                   const std::vector<Eigen::Vector3d>& current, Eigen::Matrix3d R,
                                   double threshold, int iterations) {
  const size_t n = previous.size();
  RefinedRotation out;
  std::vector<double> weight(n);
  double gate_width = 1.6 * threshold;
  for (int it = 0; it < std::max(1, iterations); ++it) {
    if (it > 0) gate_width = adaptiveGate(previous, current, R, nullptr, threshold);
    // Weighted Kabsch: the closed-form minimiser of sum w |b_prev - R b_cur|^2.
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    int used = 0;
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d rc = R * current[i];
      const double r = previous[i].cross(rc).norm();
      weight[i] = (r < kRotationGateScale * gate_width && sameHemisphere(previous[i], rc))
                      ? huberWeight(r, 0.5 * gate_width)
                      : 0.0;
      if (weight[i] > 0.0) {
        H += weight[i] * current[i] * previous[i].transpose();
        ++used;
      }
    }
    if (used < 3) break;
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
    D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
    const Eigen::Matrix3d next = svd.matrixV() * D * svd.matrixU().transpose();
    const double change = Eigen::AngleAxisd(R.transpose() * next).angle();
    R = next;
    if (change < 1e-10) break;
  }
  // Covariance of the right perturbation R exp(d): residual b_prev x R exp(d) b_cur.
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  double sum_sq = 0.0;
  int inliers = 0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d rc = R * current[i];
    const Eigen::Vector3d r = previous[i].cross(rc);
    if (r.norm() >= kRotationGateScale * threshold || !sameHemisphere(previous[i], rc)) continue;
    const Eigen::Matrix3d J = -skew(previous[i]) * R * skew(current[i]);
    A += J.transpose() * J;
    sum_sq += r.squaredNorm();
    ++inliers;
  }
  out.rotation = R;
  out.inliers = inliers;
  out.pure_rotation = true;
  const double dof = std::max(1, 2 * inliers - 3);
  const double sigma2 = sum_sq / dof;
  Eigen::FullPivLU<Eigen::Matrix3d> lu(A);
  out.covariance = lu.isInvertible() ? Eigen::Matrix3d(sigma2 * lu.inverse())
                                     : Eigen::Matrix3d(Eigen::Matrix3d::Identity());
  return out;
}

RefinedRotation refineGeneral(const std::vector<Eigen::Vector3d>& previous,
                              const std::vector<Eigen::Vector3d>& current, Eigen::Matrix3d R,
                              Eigen::Vector3d t, double threshold, int iterations) {
  const size_t n = previous.size();
  RefinedRotation out;
  Eigen::Matrix<double, 5, 5> A;
  double lambda = 1e-6;
  // The inlier gate is fixed per outer round (residuals of the round's start), so each
  // Levenberg-Marquardt step compares costs over the same matches.
  // The first round's wider gate lets a start rotation that is off by a few thresholds (a biased
  // rotation-only vote) still gather its true inliers.
  // Later rounds shrink the gate to 3.5 robust sigmas of the inliers' residuals (never above the
  // threshold): under forward motion a wrong match near the epipole satisfies the epipolar
  // constraint almost as well as a right one, and the yaw/lateral-translation ambiguity turns the
  // few that slip through a fixed gate into a visible rotation bias.
  std::vector<char> gate(n);
  double gate_width = 4.0 * threshold;
  for (int round = 0; round < 3; ++round) {
    if (round > 0) gate_width = adaptiveGate(previous, current, R, &t, threshold);
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d rc = R * current[i];
      gate[i] = std::abs(t.dot(previous[i].cross(rc))) < gate_width && sameHemisphere(previous[i], rc);
    }
    for (int it = 0; it < iterations; ++it) {
      const Eigen::Matrix<double, 3, 2> B = tangentBasis(t);
      A.setZero();
      Eigen::Matrix<double, 5, 1> g = Eigen::Matrix<double, 5, 1>::Zero();
      double current_cost = 0.0;
      int used = 0;
      for (size_t i = 0; i < n; ++i) {
        if (!gate[i]) continue;
        const Eigen::Vector3d rc = R * current[i];
        const Eigen::Vector3d normal = previous[i].cross(rc);
        const double r = t.dot(normal);
        const double w = huberWeight(r, 0.5 * threshold);
        const Eigen::Matrix<double, 1, 5> J = epipolarJacobian(previous[i], current[i], R, t, normal, B);
        A.noalias() += (w * J.transpose()) * J;
        g += w * J.transpose() * r;
        current_cost += w * r * r;
        ++used;
      }
      if (used < 6) break;
      // Levenberg-Marquardt damping: under (nearly) pure rotation the translation direction is
      // unobservable and J^T W J is singular in those two columns.
      bool improved = false;
      for (int attempt = 0; attempt < 6 && !improved; ++attempt) {
        Eigen::Matrix<double, 5, 5> damped = A;
        damped.diagonal() += lambda * (A.diagonal().array() + 1e-12).matrix();
        const Eigen::Matrix<double, 5, 1> step = damped.ldlt().solve(-g);
        if (!step.allFinite()) break;
        const Eigen::Matrix3d R_new = R * expMap(step.head<3>());
        const Eigen::Vector3d t_new = (t + B * step.tail<2>()).normalized();
        double new_cost = 0.0;
        for (size_t i = 0; i < n; ++i) {
          if (!gate[i]) continue;
          const double r = t_new.dot(previous[i].cross(R_new * current[i]));
          new_cost += huberWeight(r, 0.5 * threshold) * r * r;
        }
        if (new_cost <= current_cost) {
          improved = true;
          const bool converged = step.norm() < 1e-9;  // 6e-8 deg: far below any noise
          R = R_new;
          t = t_new;
          lambda = std::max(1e-9, lambda * 0.3);
          if (converged) it = iterations;
        } else {
          lambda *= 10.0;
        }
      }
      if (!improved) break;
    }
  }
  // Covariance: sigma^2 (J^T W J)^-1 at the solution, over the final inliers.
  const Eigen::Matrix<double, 3, 2> B = tangentBasis(t);
  A.setZero();
  double sum_sq = 0.0;
  int inliers = 0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d rc = R * current[i];
    const Eigen::Vector3d normal = previous[i].cross(rc);
    const double r = t.dot(normal);
    if (std::abs(r) >= threshold || !sameHemisphere(previous[i], rc)) continue;
    const Eigen::Matrix<double, 1, 5> J = epipolarJacobian(previous[i], current[i], R, t, normal, B);
    A += J.transpose() * J;
    sum_sq += r * r;
    ++inliers;
  }
  out.rotation = R;
  out.inliers = inliers;
  const double sigma2 = sum_sq / std::max(1, inliers - 5);
  Eigen::FullPivLU<Eigen::Matrix<double, 5, 5>> lu(A);
  if (lu.isInvertible()) {
    out.covariance = sigma2 * lu.inverse().topLeftCorner<3, 3>();
  } else {
    out.covariance = Eigen::Matrix3d::Identity();
  }
  return out;
}

}  // namespace

VerifiedRotation verifyRotation(const std::vector<Eigen::Vector3d>& previous,
                                const std::vector<Eigen::Vector3d>& current,
                                const Eigen::Matrix3d& rotation, double threshold, uint64_t seed) {
  const size_t n = previous.size();
  VerifiedRotation out;
  out.rotation = rotation;
  std::vector<Eigen::Vector3d> normals(n);
  std::vector<char> usable(n);
  std::vector<size_t> moving;  // matches a pure rotation does not explain: they carry t
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d rc = rotation * current[i];
    normals[i] = previous[i].cross(rc);
    usable[i] = sameHemisphere(previous[i], rc);
    if (!usable[i]) continue;
    // The pure-rotation residual is 2-D, the epipolar one 1-D: at equal false-rejection rates
    // (95 %: 2.45 vs 1.96 sigma) the 2-D gate is 1.25 times wider.
    if (normals[i].norm() < kRotationGateScale * threshold) {
      ++out.rotation_inliers;
    } else {
      moving.push_back(i);
    }
  }
  out.epipolar_inliers = out.rotation_inliers;
  if (moving.size() >= 2) {
    uint64_t state = seed ^ 0x5452414E534C4154ull;  // "TRANSLAT"
    const int trials = 32;  // 2-point samples among the moving matches: plenty at >= 30 % inliers
    for (int trial = 0; trial < trials; ++trial) {
      const size_t a = moving[nextRandom(&state) % moving.size()];
      const size_t b = moving[nextRandom(&state) % moving.size()];
      const Eigen::Vector3d t_raw = normals[a].cross(normals[b]);
      if (t_raw.norm() < 1e-9) continue;
      const Eigen::Vector3d t = t_raw.normalized();
      int count = 0;
      for (size_t i = 0; i < n; ++i) count += usable[i] && std::abs(t.dot(normals[i])) < threshold;
      if (count > out.epipolar_inliers) {
        out.epipolar_inliers = count;
        out.translation = t;
      }
    }
  }
  out.inliers = std::max(out.epipolar_inliers, out.rotation_inliers);
  return out;
}

RefinedRotation refineRotation(const std::vector<Eigen::Vector3d>& previous,
                               const std::vector<Eigen::Vector3d>& current,
                               const VerifiedRotation& start, double threshold, int iterations) {
  // Model selection: translation is only worth estimating when it explains clearly more matches
  // than a pure rotation does; otherwise its two extra degrees of freedom just absorb rotation
  // error (the rotation/translation ambiguity of narrow fields of view).
  // The margin also absorbs the outliers that a translation chosen among them explains by chance.
  const int extra = start.epipolar_inliers - start.rotation_inliers;
  const bool pure = start.translation.isZero() || extra < 0.15 * start.epipolar_inliers;
  if (pure) return refinePureRotation(previous, current, start.rotation, threshold, iterations);
  return refineGeneral(previous, current, start.rotation, start.translation, threshold, iterations);
}

}  // namespace visual_gyro
