#include "rotation_refinement.h"
#include "visual_gyro/geometry.h"
#include "visual_gyro/random.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace visual_gyro {

namespace {

constexpr double kRotationGateScale = 1.25;
// Translation is estimated only when it explains this fraction more matches than pure rotation.
constexpr double kTranslationGain = 0.15;

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

// Angular distance of the match from its epipolar plane: the algebraic residual t.(p x Rc) divided
// by the symmetric Sampson-style norm of its gradient. The algebraic residual shrinks with the
// distance of the bearings from the epipole, so wrong matches near the focus of expansion pass an
// algebraic gate as easily as right ones; the geometric residual treats every match alike.
double epipolarScale(const Eigen::Vector3d& t, const Eigen::Vector3d& p, const Eigen::Vector3d& rc) {
  const double tp = t.dot(p), trc = t.dot(rc);  // |t x v|^2 = 1 - (t.v)^2 for unit vectors
  return 1.0 / std::sqrt(std::max(1.0 - 0.5 * (tp * tp + trc * trc), 1e-6));
}

// Tukey's biweight with cut-off c: matches near the gate, most likely wrong ones that slipped in,
// lose their influence smoothly instead of pulling with a constant (Huber) force.
double tukeyWeight(double r, double c) {
  const double u = r / c;
  return std::abs(u) >= 1.0 ? 0.0 : (1.0 - u * u) * (1.0 - u * u);
}
double tukeyCost(double r, double c) {
  const double u = std::min(1.0, (r / c) * (r / c));
  return c * c / 6.0 * (1.0 - (1.0 - u) * (1.0 - u) * (1.0 - u));
}

// epipolarScale(t, p, rc) * |t . normal| < gate without a square root or a division (this runs
// for every match of every translation sample). The scale is >= 1 for unit vectors, so a large
// algebraic residual rejects at once.
inline bool withinEpipolarGate(const Eigen::Vector3d& t, const Eigen::Vector3d& p,
                               const Eigen::Vector3d& rc, const Eigen::Vector3d& normal, double gate) {
  const double algebraic = t.dot(normal);
  if (std::abs(algebraic) >= gate) return false;
  const double tp = t.dot(p), trc = t.dot(rc);
  const double squared = std::max(1.0 - 0.5 * (tp * tp + trc * trc), 1e-6);  // |t x v|^2 = 1 - (t.v)^2
  return algebraic * algebraic < gate * gate * squared;
}

double huberWeight(double r, double k) {
  const double a = std::abs(r);
  return a <= k ? 1.0 : k / a;
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
    const double r = t != nullptr ? std::abs(t->dot(normal)) * epipolarScale(*t, previous[i], rc)
                                  : normal.norm();
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
  out.residual_sigma = std::sqrt(sigma2);
  Eigen::FullPivLU<Eigen::Matrix3d> lu(A);
  out.covariance = lu.isInvertible() ? Eigen::Matrix3d(sigma2 * lu.inverse())
                                     : Eigen::Matrix3d(Eigen::Matrix3d::Identity());
  return out;
}

struct NormalEquations {
  Eigen::Matrix<double, 5, 5> A;
  Eigen::Matrix<double, 5, 1> g;
  Eigen::Matrix<double, 3, 2> B;  // tangent basis of t the step's last two entries refer to
  double cost = 0.0;
  int used = 0;
};

RefinedRotation refineGeneral(const std::vector<Eigen::Vector3d>& previous,
                              const std::vector<Eigen::Vector3d>& current, Eigen::Matrix3d R,
                              Eigen::Vector3d t, double threshold, int iterations, bool warm) {
  const size_t n = previous.size();
  RefinedRotation out;
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
  const double schedule[] = {6.0 * threshold, 2.0 * threshold, 0.0};
  const int rounds = static_cast<int>(sizeof(schedule) / sizeof(schedule[0]));
  // A warm start (already refined once) is inside the basin: only the adaptive rounds remain.
  for (int round = warm ? rounds - 1 : 0; round < rounds; ++round) {
    double gate_width = schedule[round];
    if (gate_width == 0.0) gate_width = adaptiveGate(previous, current, R, &t, threshold);
    // The wide early gates only need to move the start into the basin: a few steps suffice.
    const bool last = round + 1 == rounds;
    const int round_iterations = last ? iterations : std::min(iterations, 2);
    // ... on every other match: enough to find the basin; the last round uses them all.
    const size_t stride = last || n < 300 ? 1 : 2;
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d rc = R * current[i];
      gate[i] = i % stride == 0 &&
                withinEpipolarGate(t, previous[i], rc, previous[i].cross(rc), gate_width) &&
                sameHemisphere(previous[i], rc);
    }
    // One pass gives both the cost at (R, t) and the normal equations for the next step, so an
    // accepted Levenberg-Marquardt step costs one pass over the matches, not two.
    auto accumulate = [&](const Eigen::Matrix3d& Rx, const Eigen::Vector3d& tx, NormalEquations* ne) {
      const Eigen::Matrix<double, 3, 2> B = tangentBasis(tx);
      ne->A.setZero();
      ne->g.setZero();
      ne->cost = 0.0;
      ne->used = 0;
      for (size_t i = 0; i < n; ++i) {
        if (!gate[i]) continue;
        const Eigen::Vector3d rc = Rx * current[i];
        const Eigen::Vector3d normal = previous[i].cross(rc);
        // Iteratively reweighted: the scale is held fixed within a step (Sampson's approximation).
        const double scale = epipolarScale(tx, previous[i], rc);
        const double r = tx.dot(normal) * scale;
        const double w = tukeyWeight(r, gate_width);
        ne->cost += tukeyCost(r, gate_width);
        ++ne->used;
        if (w == 0.0) continue;
        const Eigen::Matrix<double, 1, 5> J = scale * epipolarJacobian(previous[i], current[i], Rx, tx, normal, B);
        ne->A.noalias() += (w * J.transpose()) * J;
        ne->g.noalias() += (w * r) * J.transpose();
      }
      ne->B = B;
    };
    NormalEquations here, there;
    accumulate(R, t, &here);
    for (int it = 0; it < round_iterations && here.used >= 6; ++it) {
      // Levenberg-Marquardt damping: under (nearly) pure rotation the translation direction is
      // unobservable and J^T W J is singular in those two columns.
      Eigen::Matrix<double, 5, 5> damped = here.A;
      damped.diagonal() += lambda * (here.A.diagonal().array() + 1e-12).matrix();
      const Eigen::Matrix<double, 5, 1> step = damped.ldlt().solve(-here.g);
      if (!step.allFinite()) break;
      const Eigen::Matrix3d R_new = R * so3Exp(step.head<3>());
      const Eigen::Vector3d t_new = (t + here.B * step.tail<2>()).normalized();
      accumulate(R_new, t_new, &there);
      if (there.cost <= here.cost) {
        R = R_new;
        t = t_new;
        std::swap(here, there);
        lambda = std::max(1e-9, lambda * 0.3);
        if (step.norm() < 1e-6) break;  // 6e-5 deg: far below any noise
      } else {
        lambda *= 10.0;
        if (lambda > 1e6) break;
      }
    }
  }
  // Covariance: sigma^2 (J^T W J)^-1 at the solution, over the final inliers.
  const Eigen::Matrix<double, 3, 2> B = tangentBasis(t);
  Eigen::Matrix<double, 5, 5> A = Eigen::Matrix<double, 5, 5>::Zero();
  double sum_sq = 0.0;
  int inliers = 0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d rc = R * current[i];
    const Eigen::Vector3d normal = previous[i].cross(rc);
    const double scale = epipolarScale(t, previous[i], rc);
    const double r = t.dot(normal) * scale;
    if (std::abs(r) >= threshold || !sameHemisphere(previous[i], rc)) continue;
    const Eigen::Matrix<double, 1, 5> J =
        scale * epipolarJacobian(previous[i], current[i], R, t, normal, B);
    A += J.transpose() * J;
    sum_sq += r * r;
    ++inliers;
  }
  out.rotation = R;
  out.translation = t;
  out.inliers = inliers;
  const double sigma2 = sum_sq / std::max(1, inliers - 5);
  out.residual_sigma = std::sqrt(sigma2);
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
  std::vector<Eigen::Vector3d> normals(n), rotated(n);
  std::vector<char> usable(n);
  std::vector<size_t> moving;  // matches a pure rotation does not explain: they carry t
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d rc = rotation * current[i];
    rotated[i] = rc;
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
  auto countInliers = [&](const Eigen::Vector3d& t, size_t stride) {
    int count = 0;
    for (size_t i = 0; i < n; i += stride)
      count += usable[i] && withinEpipolarGate(t, previous[i], rotated[i], normals[i], threshold);
    return count;
  };
  // Samples are scored on every other match (counts doubled); the winner is recounted on all.
  const size_t sample_stride = n >= 200 ? 2 : 1;
  // A translation can at best add the moving matches to the rotation inliers; when they are too
  // few to pass the model selection in refineRotation (kTranslationGain), the search is moot.
  const bool translation_can_win =
      moving.size() >= 2 && moving.size() >= kTranslationGain * out.rotation_inliers;
  if (translation_can_win) {
    SplitMix64 rng(seed ^ 0x5452414E534C4154ull);  // "TRANSLAT"
    // 2-point samples among the moving matches, stopped adaptively: once the best translation
    // explains a fraction w of them, log(0.01) / log(1 - w^2) samples find a clean pair with 99 %
    // probability (at most 64, enough for 50 % wrong matches); the best is then refitted.
    int trials = 64;
    for (int trial = 0; trial < trials; ++trial) {
      const size_t a = moving[rng.next() % moving.size()];
      const size_t b = moving[rng.next() % moving.size()];
      const Eigen::Vector3d t_raw = normals[a].cross(normals[b]);
      if (t_raw.norm() < 1e-9) continue;
      const Eigen::Vector3d t = t_raw.normalized();
      const int count = static_cast<int>(sample_stride) * countInliers(t, sample_stride);
      if (count > out.epipolar_inliers) {
        out.epipolar_inliers = count;
        out.translation = t;
        const double w = std::clamp(static_cast<double>(count - out.rotation_inliers) / moving.size(), 0.01, 0.99);
        trials = std::clamp(static_cast<int>(std::ceil(std::log(0.01) / std::log(1.0 - w * w))), 8, 64);
      }
    }
    if (!out.translation.isZero()) out.epipolar_inliers = countInliers(out.translation, 1);
    // Least-squares refit: t is the eigenvector of the smallest eigenvalue of sum n n^T over the
    // inliers (each normal scaled to its angular residual), repeated while the support grows.
    for (int refit = 0; refit < 3 && !out.translation.isZero(); ++refit) {
      Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
      const Eigen::Vector3d& t = out.translation;
      for (size_t i = 0; i < n; ++i) {
        if (!usable[i]) continue;
        const double scale = epipolarScale(t, previous[i], rotated[i]);
        if (std::abs(t.dot(normals[i])) * scale >= threshold) continue;
        const Eigen::Vector3d m = scale * normals[i];
        M += m * m.transpose();
      }
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(M);
      const Eigen::Vector3d refitted = eig.eigenvectors().col(0);
      const int count = countInliers(refitted, 1);
      if (count <= out.epipolar_inliers) break;
      out.epipolar_inliers = count;
      out.translation = refitted;
    }
  }
  out.inliers = std::max(out.epipolar_inliers, out.rotation_inliers);
  return out;
}

bool explainsBetter(const RefinedRotation& a, const RefinedRotation& b) {
  if (a.pure_rotation == b.pure_rotation) return a.inliers > b.inliers;
  // The rule of refineRotation: general motion when (general - pure) >= gain * general.
  const RefinedRotation& general = a.pure_rotation ? b : a;
  const RefinedRotation& pure = a.pure_rotation ? a : b;
  const bool general_wins = general.inliers - pure.inliers >= kTranslationGain * general.inliers;
  return a.pure_rotation ? !general_wins : general_wins;
}

RefinedRotation refineRotation(const std::vector<Eigen::Vector3d>& previous,
                               const std::vector<Eigen::Vector3d>& current,
                               const VerifiedRotation& start, double threshold, int iterations,
                               bool warm) {
  // Model selection: translation is only worth estimating when it explains clearly more matches
  // than a pure rotation does; otherwise its two extra degrees of freedom just absorb rotation
  // error (the rotation/translation ambiguity of narrow fields of view).
  // The margin also absorbs the outliers that a translation chosen among them explains by chance.
  const int extra = start.epipolar_inliers - start.rotation_inliers;
  const bool pure = start.translation.isZero() || extra < kTranslationGain * start.epipolar_inliers;
  if (pure) return refinePureRotation(previous, current, start.rotation, threshold, iterations);
  return refineGeneral(previous, current, start.rotation, start.translation, threshold, iterations, warm);
}

}  // namespace visual_gyro
