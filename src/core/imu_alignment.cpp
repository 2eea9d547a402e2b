#include "visual_gyro/imu_alignment.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "visual_gyro/geometry.h"

namespace visual_gyro {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
/// Median of the chi-square distribution with 3 degrees of freedom: the median squared
/// Mahalanobis length of an honest 3-D residual.
constexpr double kChiSquare3Median = 2.366;
/// Offsets: the magnitude cross-correlation's grid, the profile cost's grid around its peak and
/// the golden-section bracket around the grid's best point [s].
constexpr double kCoarseStep = 0.0005;
constexpr double kProfileHalfWidth = 0.010;
constexpr double kProfileStep = 0.001;
constexpr double kGoldenTolerance = 1e-6;

std::string text(double value) {
  std::ostringstream out;
  out.precision(6);
  out << value;
  return out.str();
}

double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  return values[mid];
}

/// Median spacing of increasing stamps [s].
double medianInterval(const std::vector<double>& stamps) {
  std::vector<double> gaps;
  for (size_t i = 1; i < stamps.size(); ++i) gaps.push_back(stamps[i] - stamps[i - 1]);
  return median(gaps);
}

/// The gyro linearly interpolated between its samples and integrated with the trapezoid rule, as
/// Sequence integrates it (exact for that interpolation), through a table of cumulative integrals.
/// Times are relative to a reference stamp so that absolute stamps (~1e9 s) keep their precision.
class GyroIntegral {
 public:
  GyroIntegral(const std::vector<GyroSample>& imu, double reference) {
    t_.reserve(imu.size());
    for (const GyroSample& s : imu) {
      t_.push_back(s.stamp - reference);
      g_.push_back(s.angular_velocity);
    }
    cumulative_.assign(t_.size(), Eigen::Vector3d::Zero());
    for (size_t i = 1; i < t_.size(); ++i)
      cumulative_[i] = cumulative_[i - 1] + 0.5 * (t_[i] - t_[i - 1]) * (g_[i] + g_[i - 1]);
  }
  double begin() const { return t_.front(); }
  double end() const { return t_.back(); }
  /// Mean rate over [t0, t1] (t0 < t1, both inside the samples' span) [rad/s].
  Eigen::Vector3d mean(double t0, double t1) const { return (at(t1) - at(t0)) / (t1 - t0); }

 private:
  Eigen::Vector3d at(double t) const {
    const size_t n = t_.size();
    size_t i = static_cast<size_t>(std::upper_bound(t_.begin(), t_.end(), t) - t_.begin());
    i = std::min(i == 0 ? 0 : i - 1, n - 2);
    const double h = t - t_[i];
    const Eigen::Vector3d rate_t = g_[i] + (g_[i + 1] - g_[i]) * (h / (t_[i + 1] - t_[i]));
    return cumulative_[i] + 0.5 * h * (g_[i] + rate_t);
  }
  std::vector<double> t_;
  std::vector<Eigen::Vector3d> g_, cumulative_;
};

/// Per-sample white noise of the gyro [rad/s] from its second differences (which remove any
/// motion smooth over three samples): per axis 1.4826 MAD / sqrt(6), averaged in variance.
double gyroNoise(const std::vector<GyroSample>& imu) {
  if (imu.size() < 3) return 0.0;
  double variance = 0.0;
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<double> d;
    for (size_t i = 1; i + 1 < imu.size(); ++i)
      d.push_back(std::abs(imu[i + 1].angular_velocity[axis] - 2.0 * imu[i].angular_velocity[axis] +
                           imu[i - 1].angular_velocity[axis]));
    const double sigma = 1.4826 * median(d) / std::sqrt(6.0);
    variance += sigma * sigma / 3.0;
  }
  return std::sqrt(variance);
}

/// One used frame: its interval (relative to the reference stamp), visual rate and covariance,
/// and the variance of the IMU's mean rate over it (per axis).
struct Frame {
  double start = 0.0, end = 0.0;
  Eigen::Vector3d rate = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  double imu_variance = 0.0;
};

/// The gyro model: measured = diag(scale) * rotation * visual + bias.
struct Model {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
};

/// Weighted Pearson correlation of a and b.
double correlation(const std::vector<double>& a, const std::vector<double>& b, const std::vector<double>& w) {
  double sw = 0, ma = 0, mb = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    sw += w[k];
    ma += w[k] * a[k];
    mb += w[k] * b[k];
  }
  ma /= sw;
  mb /= sw;
  double cab = 0, caa = 0, cbb = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    cab += w[k] * (a[k] - ma) * (b[k] - mb);
    caa += w[k] * (a[k] - ma) * (a[k] - ma);
    cbb += w[k] * (b[k] - mb) * (b[k] - mb);
  }
  return caa > 0 && cbb > 0 ? cab / std::sqrt(caa * cbb) : 0.0;
}

/// Minimum of f on [lo, hi] by golden-section search (f unimodal there).
template <typename F>
double goldenSection(F f, double lo, double hi) {
  const double ratio = 0.5 * (std::sqrt(5.0) - 1.0);
  double a = lo, b = hi;
  double c = b - ratio * (b - a), d = a + ratio * (b - a);
  double fc = f(c), fd = f(d);
  while (b - a > kGoldenTolerance) {
    if (fc < fd) {
      b = d;
      d = c;
      fd = fc;
      c = b - ratio * (b - a);
      fc = f(c);
    } else {
      a = c;
      c = d;
      fc = fd;
      d = a + ratio * (b - a);
      fd = f(d);
    }
  }
  return 0.5 * (a + b);
}

/// Symmetric pseudo-inverse: directions the information does not constrain get a huge variance, so
/// that the marginals show them as not observable.
Eigen::MatrixXd covarianceFromInformation(const Eigen::MatrixXd& information) {
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(information);
  const double largest = std::max(eigen.eigenvalues().maxCoeff(), 0.0);
  Eigen::VectorXd inverse(eigen.eigenvalues().size());
  for (int i = 0; i < inverse.size(); ++i) {
    const double lambda = eigen.eigenvalues()[i];
    inverse[i] = lambda > 1e-12 * largest && lambda > 0.0 ? 1.0 / lambda : 1e12;
  }
  return eigen.eigenvectors() * inverse.asDiagonal() * eigen.eigenvectors().transpose();
}

/// The weighted least-squares fit of the gyro model to the IMU's mean rates over the frames'
/// intervals shifted by an offset, with Huber weights per frame.
class Fit {
 public:
  Fit(const std::vector<Frame>& frames, const GyroIntegral& gyro, const ImuAlignmentSettings& settings)
      : frames_(frames), gyro_(gyro), settings_(settings), means_(frames.size()), robust_(frames.size(), 1.0) {
    rotation_params_ = settings.rotation_known ? 0 : 3;
    params_ = rotation_params_ + 3 + (settings.estimate_scale ? 3 : 0);
  }

  int parameters() const { return params_; }
  size_t size() const { return frames_.size(); }

  /// The IMU's mean rates over the frames' intervals moved by `offset` [s].
  void setOffset(double offset) {
    for (size_t k = 0; k < frames_.size(); ++k)
      means_[k] = gyro_.mean(frames_[k].start + offset, frames_[k].end + offset);
  }

  /// Weighted Procrustes (Kabsch) with a bias, scalar weights from the covariances: the start of
  /// the Gauss-Newton iterations (scale 1).
  Model kabsch() const {
    Model model;
    double total = 0.0;
    Eigen::Vector3d v_mean = Eigen::Vector3d::Zero(), m_mean = Eigen::Vector3d::Zero();
    std::vector<double> w(frames_.size());
    for (size_t k = 0; k < frames_.size(); ++k) {
      w[k] = robust_[k] / (frames_[k].covariance.trace() / 3.0 + frames_[k].imu_variance);
      total += w[k];
      v_mean += w[k] * frames_[k].rate;
      m_mean += w[k] * means_[k];
    }
    v_mean /= total;
    m_mean /= total;
    if (settings_.rotation_known) {
      model.rotation = settings_.known_imu_from_camera;
    } else {
      Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
      for (size_t k = 0; k < frames_.size(); ++k)
        h += w[k] * (frames_[k].rate - v_mean) * (means_[k] - m_mean).transpose();
      const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
      Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
      d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
      model.rotation = svd.matrixV() * d * svd.matrixU().transpose();
    }
    model.bias = m_mean - model.rotation * v_mean;
    return model;
  }

  /// Residual of frame k and its information matrix (inverse covariance) under `model`.
  Eigen::Vector3d residual(const Model& model, size_t k, Eigen::Matrix3d* information) const {
    const Frame& f = frames_[k];
    const Eigen::Matrix3d dr = model.scale.asDiagonal() * model.rotation;
    if (information != nullptr) {
      const Eigen::Matrix3d sigma = dr * f.covariance * dr.transpose() + f.imu_variance * Eigen::Matrix3d::Identity();
      *information = sigma.ldlt().solve(Eigen::Matrix3d::Identity());
    }
    return means_[k] - dr * f.rate - model.bias;
  }

  /// Sum over frames of robust weight * Mahalanobis length^2.
  double cost(const Model& model) const {
    double sum = 0.0;
    Eigen::Matrix3d w;
    for (size_t k = 0; k < frames_.size(); ++k) {
      const Eigen::Vector3d r = residual(model, k, &w);
      sum += robust_[k] * r.dot(w * r);
    }
    return sum;
  }

  /// The cost of a bias alone (the camera ignored), with the information matrices of `model`, and
  /// that bias: how much of the IMU's variation there is to explain.
  double biasOnlyCost(const Model& model, Eigen::Vector3d* bias, Eigen::Matrix3d* bias_information) const {
    Eigen::Matrix3d sum_w = Eigen::Matrix3d::Zero();
    Eigen::Vector3d sum_wm = Eigen::Vector3d::Zero();
    std::vector<Eigen::Matrix3d> w(frames_.size());
    for (size_t k = 0; k < frames_.size(); ++k) {
      residual(model, k, &w[k]);
      sum_w += robust_[k] * w[k];
      sum_wm += robust_[k] * w[k] * means_[k];
    }
    *bias = sum_w.ldlt().solve(sum_wm);
    *bias_information = sum_w;
    double sum = 0.0;
    for (size_t k = 0; k < frames_.size(); ++k) {
      const Eigen::Vector3d r = means_[k] - *bias;
      sum += robust_[k] * r.dot(w[k] * r);
    }
    return sum;
  }

  /// Gauss-Newton on rotation (unless known), bias and scale (when estimated) with the current
  /// robust weights; fills the information matrix of the last linearisation. Returns the cost.
  double solve(Model* model, int iterations, Eigen::MatrixXd* information = nullptr) const {
    Eigen::MatrixXd h(params_, params_);
    Eigen::VectorXd g(params_);
    for (int it = 0; it < iterations; ++it) {
      linearise(*model, &h, &g);
      const double damping = 1e-12 * std::max(h.trace(), 1e-30);
      const Eigen::VectorXd step =
          -(h + damping * Eigen::MatrixXd::Identity(params_, params_)).ldlt().solve(g);
      if (!step.allFinite()) break;
      int at = 0;
      if (rotation_params_ > 0) {
        model->rotation = so3Exp(step.segment<3>(0)) * model->rotation;
        at = 3;
      }
      model->bias += step.segment<3>(at);
      if (settings_.estimate_scale) model->scale += step.segment<3>(at + 3);
      if (step.norm() < 1e-12) break;
    }
    if (information != nullptr) {
      linearise(*model, &h, &g);
      *information = h;
    }
    return cost(*model);
  }

  /// Huber weights from the residuals under `model`, in units of their robust spread.
  void reweight(const Model& model) {
    std::vector<double> length(frames_.size());
    Eigen::Matrix3d w;
    for (size_t k = 0; k < frames_.size(); ++k) {
      const Eigen::Vector3d r = residual(model, k, &w);
      length[k] = std::sqrt(std::max(r.dot(w * r), 0.0));
    }
    const double spread = std::max(median(length) / std::sqrt(kChiSquare3Median), 1e-300);
    const double limit = settings_.huber_threshold * spread * std::sqrt(kChiSquare3Median);
    for (size_t k = 0; k < frames_.size(); ++k) robust_[k] = length[k] <= limit ? 1.0 : limit / length[k];
  }

  /// Root mean square of the residuals under `model` [rad/s] (unweighted).
  double rmse(const Model& model) const {
    double sum = 0.0;
    for (size_t k = 0; k < frames_.size(); ++k) sum += residual(model, k, nullptr).squaredNorm();
    return std::sqrt(sum / frames_.size());
  }

  /// Frame k's visual rate and the IMU's mean over it.
  const Frame& frame(size_t k) const { return frames_[k]; }
  const Eigen::Vector3d& imuMean(size_t k) const { return means_[k]; }
  /// Scalar weight of frame k for the magnitude correlation (covariances and robust weight).
  double scalarWeight(size_t k) const {
    return robust_[k] / (frames_[k].covariance.trace() / 3.0 + frames_[k].imu_variance);
  }

 private:
  void linearise(const Model& model, Eigen::MatrixXd* h, Eigen::VectorXd* g) const {
    h->setZero();
    g->setZero();
    Eigen::MatrixXd jacobian(3, params_);
    Eigen::Matrix3d w;
    for (size_t k = 0; k < frames_.size(); ++k) {
      const Eigen::Vector3d r = residual(model, k, &w);
      const Eigen::Vector3d rotated = model.rotation * frames_[k].rate;
      int at = 0;
      // r = m - D R v - b; a left perturbation R <- exp(d) R moves R v by d x (R v).
      if (rotation_params_ > 0) {
        jacobian.block<3, 3>(0, 0) = model.scale.asDiagonal() * skew(rotated);
        at = 3;
      }
      jacobian.block<3, 3>(0, at) = -Eigen::Matrix3d::Identity();
      if (settings_.estimate_scale) jacobian.block<3, 3>(0, at + 3) = -Eigen::Matrix3d(rotated.asDiagonal());
      *h += robust_[k] * jacobian.transpose() * w * jacobian;
      *g += robust_[k] * jacobian.transpose() * w * r;
    }
  }

  const std::vector<Frame>& frames_;
  const GyroIntegral& gyro_;
  const ImuAlignmentSettings& settings_;
  std::vector<Eigen::Vector3d> means_;
  std::vector<double> robust_;
  int rotation_params_ = 3;
  int params_ = 6;
};

/// The offset [s] in [-max, max] whose IMU rate magnitudes (less `bias`) correlate best with the
/// visual rate magnitudes: independent of the unknown rotation.
double magnitudePeak(Fit* fit, double max_offset, const Eigen::Vector3d& bias) {
  std::vector<double> visual(fit->size()), imu(fit->size()), w(fit->size());
  for (size_t k = 0; k < fit->size(); ++k) {
    visual[k] = fit->frame(k).rate.norm();
    w[k] = fit->scalarWeight(k);
  }
  const int steps = static_cast<int>(std::floor(max_offset / kCoarseStep));
  double best = -kInfinity, best_offset = 0.0;
  for (int i = -steps; i <= steps; ++i) {
    const double offset = i * kCoarseStep;
    fit->setOffset(offset);
    for (size_t k = 0; k < fit->size(); ++k) imu[k] = (fit->imuMean(k) - bias).norm();
    const double c = correlation(visual, imu, w);
    if (c > best) {
      best = c;
      best_offset = offset;
    }
  }
  return best_offset;
}

/// The model fitted at `offset` from scratch (Kabsch, then Gauss-Newton), with Huber weights
/// renewed a few times.
Model robustFit(Fit* fit, double offset) {
  fit->setOffset(offset);
  Model model = fit->kabsch();
  fit->solve(&model, 10);
  for (int round = 0; round < 4; ++round) {
    fit->reweight(model);
    model = fit->kabsch();
    fit->solve(&model, 10);
  }
  return model;
}

/// The profile cost at `offset`: the model refitted (robust weights held) from `start`.
double profileCost(Fit* fit, double offset, const Model& start, Model* fitted = nullptr) {
  fit->setOffset(offset);
  Model model = start;
  const double cost = fit->solve(&model, 6);
  if (fitted != nullptr) *fitted = model;
  return cost;
}

/// Offset refinement: the profile cost on a 1 ms grid within 10 ms of `offset`, then golden-section
/// within a grid step of its lowest point, robust weights renewed in between.
double refineOffset(Fit* fit, double offset, double max_offset, Model* model) {
  for (int round = 0; round < 3; ++round) {
    const Model start = *model;
    double best = kInfinity, best_offset = offset;
    for (double o = offset - kProfileHalfWidth; o <= offset + kProfileHalfWidth + 1e-12; o += kProfileStep) {
      const double clamped = std::clamp(o, -max_offset, max_offset);
      const double cost = profileCost(fit, clamped, start);
      if (cost < best) {
        best = cost;
        best_offset = clamped;
      }
    }
    const double lo = std::max(best_offset - kProfileStep, -max_offset);
    const double hi = std::min(best_offset + kProfileStep, max_offset);
    const double refined = goldenSection([&](double o) { return profileCost(fit, o, start); }, lo, hi);
    profileCost(fit, refined, start, model);
    fit->reweight(*model);
    fit->solve(model, 10);
    const bool settled = std::abs(refined - offset) < 1e-5;
    offset = refined;
    if (settled && round > 0) break;
  }
  return offset;
}

/// The used frames: valid, finite, and inside the IMU's span at every searched offset.
std::vector<Frame> usableFrames(const std::vector<VisualRate>& rates, const GyroIntegral& gyro, double reference,
                                double gyro_noise, double imu_interval, const ImuAlignmentSettings& settings,
                                int* valid) {
  std::vector<Frame> frames;
  *valid = 0;
  for (const VisualRate& r : rates) {
    if (!r.valid) continue;
    ++*valid;
    if (!(r.end > r.start) || !r.rate.allFinite() || !r.covariance.allFinite()) continue;
    if (r.covariance.ldlt().info() != Eigen::Success || !(r.covariance.trace() > 0.0)) continue;
    Frame f;
    f.start = r.start - reference;
    f.end = r.end - reference;
    if (f.start - settings.max_offset < gyro.begin() || f.end + settings.max_offset > gyro.end()) continue;
    f.rate = r.rate;
    f.covariance = 0.5 * (r.covariance + r.covariance.transpose());
    // The IMU's mean over the interval averages about (end - start) / interval samples.
    const double noise = std::max(gyro_noise, 1e-9);
    f.imu_variance = noise * noise * std::min(1.0, imu_interval / (f.end - f.start));
    frames.push_back(f);
  }
  return frames;
}

void checkSettings(const ImuAlignmentSettings& s) {
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(s.max_offset))
    throw std::invalid_argument("alignImu: max_offset must be > 0, got " + text(s.max_offset));
  if (!positive(s.huber_threshold)) throw std::invalid_argument("alignImu: huber_threshold must be > 0");
  if (!(s.min_explained >= 0.0 && s.min_explained < 1.0))
    throw std::invalid_argument("alignImu: min_explained must lie in [0, 1)");
  if (!positive(s.max_offset_sigma) || !positive(s.max_rotation_sigma_deg))
    throw std::invalid_argument("alignImu: the observability limits must be > 0");
  if (s.min_frames < 3) throw std::invalid_argument("alignImu: min_frames must be >= 3");
  if (!positive(s.min_samples_per_frame)) throw std::invalid_argument("alignImu: min_samples_per_frame must be > 0");
  if (s.rotation_known &&
      (!s.known_imu_from_camera.allFinite() ||
       (s.known_imu_from_camera.transpose() * s.known_imu_from_camera - Eigen::Matrix3d::Identity()).norm() > 1e-6 ||
       s.known_imu_from_camera.determinant() < 0.0))
    throw std::invalid_argument("alignImu: known_imu_from_camera is not a rotation");
}

/// Offset uncertainty [s] from the profile cost's curvature at `offset`, scaled by the reduced
/// chi-square `scale2`: the variance of a least-squares parameter is 2 / J'' (J = chi-square).
double offsetSigma(Fit* fit, double offset, double max_offset, double imu_interval, const Model& model,
                   double scale2) {
  const double h = std::max(0.001, imu_interval);
  if (offset - h < -max_offset || offset + h > max_offset) return kInfinity;
  const double c0 = profileCost(fit, offset, model);
  const double cm = profileCost(fit, offset - h, model);
  const double cp = profileCost(fit, offset + h, model);
  const double curvature = (cp - 2.0 * c0 + cm) / (h * h);
  fit->setOffset(offset);
  return curvature > 0.0 ? std::sqrt(2.0 * scale2 / curvature) : kInfinity;
}

/// Fills the rotation's observability, uncertainty and (for kAxisOnly) axis from the parameters'
/// covariance (rotation block first).
void judgeRotation(const Eigen::MatrixXd& covariance, const Model& model, const ImuAlignmentSettings& settings,
                   ImuAlignment* out) {
  out->imu_from_camera = Eigen::Quaterniond(model.rotation).normalized();
  if (settings.rotation_known) {
    out->rotation = RotationObservability::kKnown;
    return;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(Eigen::Matrix3d(covariance.block<3, 3>(0, 0)));
  const Eigen::Vector3d sigma_deg = eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt() * kRadToDeg;  // ascending
  out->rotation_sigma_deg = sigma_deg[2];
  const int weak = static_cast<int>((sigma_deg.array() > settings.max_rotation_sigma_deg).count());
  if (!out->motion || weak >= 2) {
    out->rotation = RotationObservability::kNone;
    out->notes.push_back(out->motion ? "rotation not observable: it is uncertain by " + text(sigma_deg[1]) +
                                           " deg or more about two axes (more rotation about all axes is needed)"
                                     : "rotation not observable: the camera saw no rotation");
    return;
  }
  if (weak == 1) {
    out->rotation = RotationObservability::kAxisOnly;
    Eigen::Vector3d axis_imu = eigen.eigenvectors().col(2).normalized();
    Eigen::Vector3d axis_camera = model.rotation.transpose() * axis_imu;
    Eigen::Index largest = 0;
    axis_camera.cwiseAbs().maxCoeff(&largest);
    if (axis_camera[largest] < 0) {
      axis_camera = -axis_camera;
      axis_imu = -axis_imu;
    }
    out->rotation_axis_camera = axis_camera;
    out->rotation_axis_imu = axis_imu;
    out->notes.push_back("rotation observable about one axis only: the camera's axis (" + text(axis_camera.x()) +
                         ", " + text(axis_camera.y()) + ", " + text(axis_camera.z()) + ") is the IMU's (" +
                         text(axis_imu.x()) + ", " + text(axis_imu.y()) + ", " + text(axis_imu.z()) +
                         "), the angle about it is unknown (uncertain by " + text(sigma_deg[2]) +
                         " deg); rotate about another axis too");
    return;
  }
  out->rotation = RotationObservability::kFull;
}

/// Offset, rotation, bias and scale once the camera saw rotation.
void alignWithMotion(Fit* fit, double offset, double imu_interval, const ImuAlignmentSettings& settings,
                     Model* model, ImuAlignment* out) {
  const double dof = std::max(1.0, 3.0 * fit->size() - fit->parameters() - 1.0);
  Eigen::MatrixXd information;
  const double cost = fit->solve(model, 10, &information);
  const double scale2 = cost / dof;
  const Eigen::MatrixXd covariance = scale2 * covarianceFromInformation(information);
  out->time_offset_sigma = offsetSigma(fit, offset, settings.max_offset, imu_interval, *model, scale2);
  const bool at_edge = std::abs(offset) > settings.max_offset - 2.0 * kProfileStep;
  out->offset_observable = !at_edge && out->time_offset_sigma <= settings.max_offset_sigma;
  out->time_offset = out->offset_observable ? offset : 0.0;
  if (at_edge) {
    out->notes.push_back("time offset not observable: the best offset lies at the edge of the searched +-" +
                         text(settings.max_offset * 1e3) + " ms (widen the search)");
  } else if (!out->offset_observable) {
    out->notes.push_back("time offset not observable: uncertain by " + text(out->time_offset_sigma * 1e3) +
                         " ms (the rates must change faster, or over more frames)");
  }
  judgeRotation(covariance, *model, settings, out);
  const int at = settings.rotation_known ? 0 : 3;
  out->gyro_bias = model->bias;
  out->gyro_bias_sigma = covariance.block<3, 3>(at, at).diagonal().cwiseMax(0.0).cwiseSqrt();
  if (settings.estimate_scale) {
    out->gyro_scale = model->scale;
    out->gyro_scale_sigma = covariance.block<3, 3>(at + 3, at + 3).diagonal().cwiseMax(0.0).cwiseSqrt();
  }
  out->rate_rmse = fit->rmse(*model);
}

/// No rotation seen: the camera stood still, so the IMU's (weighted) mean over the frames is its
/// bias; offset and rotation are not observable (the rotation stays the known one when given).
void alignStill(Fit* fit, const Model& model, const ImuAlignmentSettings& settings, ImuAlignment* out) {
  out->notes.push_back("time offset not observable: the camera saw no rotation (its rates explain " +
                       text(100.0 * std::max(out->explained, 0.0)) + " % of the IMU's rate variation)");
  fit->setOffset(0.0);
  Eigen::Vector3d bias;
  Eigen::Matrix3d bias_information;
  const double cost = fit->biasOnlyCost(model, &bias, &bias_information);
  const double dof = std::max(1.0, 3.0 * fit->size() - 3.0);
  out->gyro_bias = bias;
  out->gyro_bias_sigma = (cost / dof * bias_information.inverse()).diagonal().cwiseMax(0.0).cwiseSqrt();
  out->rotation_sigma_deg = kInfinity;
  if (settings.rotation_known) {
    out->rotation = RotationObservability::kKnown;
    out->imu_from_camera = Eigen::Quaterniond(settings.known_imu_from_camera).normalized();
  } else {
    out->rotation = RotationObservability::kNone;
    out->notes.push_back("rotation not observable: the camera saw no rotation");
  }
  if (settings.estimate_scale) out->notes.push_back("gyro scale not observable: the camera saw no rotation");
  // With the rotation unknown the two rates cannot be subtracted; both deviate from zero
  // independently, so their squared lengths add (exactly what any rotation of one would give on
  // average).
  double sum = 0.0;
  for (size_t k = 0; k < fit->size(); ++k) {
    const Eigen::Vector3d imu = fit->imuMean(k) - bias;
    sum += settings.rotation_known
               ? (imu - settings.known_imu_from_camera * fit->frame(k).rate).squaredNorm()
               : imu.squaredNorm() + fit->frame(k).rate.squaredNorm();
  }
  out->rate_rmse = std::sqrt(sum / fit->size());
}

}  // namespace

bool visualRateOf(const FrameResult& result, double stamp, VisualRate* rate) {
  if (rate == nullptr || result.skipped() || result.status == FrameStatus::kFirstFrame || !(result.dt > 0.0))
    return false;
  rate->start = stamp - result.dt;
  rate->end = stamp;
  rate->valid = result.hasEstimate();
  rate->rate = rate->valid ? result.angular_velocity : Eigen::Vector3d::Zero();
  rate->covariance = result.angular_velocity_covariance;
  return true;
}

const char* rotationObservabilityName(RotationObservability observability) {
  switch (observability) {
    case RotationObservability::kFull: return "full";
    case RotationObservability::kAxisOnly: return "axis_only";
    case RotationObservability::kNone: return "none";
    case RotationObservability::kKnown: return "known";
  }
  return "?";
}

void checkImuSamples(const std::vector<GyroSample>& imu, const std::vector<double>& frame_stamps,
                     const ImuAlignmentSettings& settings) {
  if (imu.empty()) throw ImuAlignmentError("no IMU samples");
  if (imu.size() < 2) throw ImuAlignmentError("only one IMU sample");
  for (size_t i = 0; i < imu.size(); ++i) {
    if (!std::isfinite(imu[i].stamp) || !imu[i].angular_velocity.allFinite())
      throw ImuAlignmentError("IMU sample " + std::to_string(i) + " has a stamp or rate that is not finite");
    if (i > 0 && !(imu[i].stamp > imu[i - 1].stamp))
      throw ImuAlignmentError("IMU stamps must increase: sample " + std::to_string(i) + " (" + text(imu[i].stamp) +
                              " s) is not after sample " + std::to_string(i - 1) + " (" + text(imu[i - 1].stamp) +
                              " s)");
  }
  if (frame_stamps.size() < 2) throw ImuAlignmentError("fewer than two images");
  const double first = *std::min_element(frame_stamps.begin(), frame_stamps.end());
  const double last = *std::max_element(frame_stamps.begin(), frame_stamps.end());
  if (imu.back().stamp <= first || imu.front().stamp >= last) {
    throw ImuAlignmentError("the IMU stamps (" + text(imu.front().stamp) + " .. " + text(imu.back().stamp) +
                            " s) do not overlap the images' (" + text(first) + " .. " + text(last) +
                            " s): are both on the same clock?");
  }
  std::vector<double> imu_stamps(imu.size()), sorted_frames = frame_stamps;
  for (size_t i = 0; i < imu.size(); ++i) imu_stamps[i] = imu[i].stamp;
  std::sort(sorted_frames.begin(), sorted_frames.end());
  const double imu_interval = medianInterval(imu_stamps);
  const double frame_interval = medianInterval(sorted_frames);
  if (imu_interval * settings.min_samples_per_frame > frame_interval) {
    throw ImuAlignmentError("the IMU samples at " + text(1.0 / imu_interval) + " Hz, " +
                            text(frame_interval / imu_interval) + " samples per frame interval of the " +
                            text(1.0 / frame_interval) + " Hz camera; at least " +
                            text(settings.min_samples_per_frame) + " are needed");
  }
}

ImuAlignment alignImu(const std::vector<VisualRate>& rates, const std::vector<GyroSample>& imu,
                      const ImuAlignmentSettings& settings) {
  checkSettings(settings);
  std::vector<double> frame_stamps;
  for (const VisualRate& r : rates) {
    frame_stamps.push_back(r.start);
    frame_stamps.push_back(r.end);
  }
  std::sort(frame_stamps.begin(), frame_stamps.end());
  frame_stamps.erase(std::unique(frame_stamps.begin(), frame_stamps.end()), frame_stamps.end());
  checkImuSamples(imu, frame_stamps, settings);

  ImuAlignment out;
  out.frames = static_cast<int>(rates.size());
  out.imu_samples = static_cast<int>(imu.size());
  std::vector<double> imu_stamps;
  for (const GyroSample& s : imu) imu_stamps.push_back(s.stamp);
  const double imu_interval = medianInterval(imu_stamps);
  out.imu_rate_hz = 1.0 / imu_interval;
  out.gyro_noise = gyroNoise(imu);
  const double reference = frame_stamps.front();
  const GyroIntegral gyro(imu, reference);
  const std::vector<Frame> frames =
      usableFrames(rates, gyro, reference, out.gyro_noise, imu_interval, settings, &out.frames_valid);
  out.frames_used = static_cast<int>(frames.size());
  if (out.frames_used < settings.min_frames) {
    throw ImuAlignmentError(std::to_string(out.frames_valid) + " valid frames, of which " +
                            std::to_string(out.frames_used) + " lie inside the IMU's span at every offset up to +-" +
                            text(settings.max_offset * 1e3) + " ms; at least " + std::to_string(settings.min_frames) +
                            " are needed");
  }

  Fit fit(frames, gyro, settings);
  out.has_scale = settings.estimate_scale;
  // Coarse: rate magnitudes do not depend on the rotation; again once the bias is known.
  double offset = magnitudePeak(&fit, settings.max_offset, Eigen::Vector3d::Zero());
  Model model = robustFit(&fit, offset);
  offset = magnitudePeak(&fit, settings.max_offset, model.bias);
  model = robustFit(&fit, offset);
  offset = refineOffset(&fit, offset, settings.max_offset, &model);

  fit.setOffset(offset);
  Eigen::Vector3d bias_only;
  Eigen::Matrix3d bias_information;
  const double cost = fit.cost(model);
  const double null_cost = fit.biasOnlyCost(model, &bias_only, &bias_information);
  out.explained = null_cost > 0.0 ? 1.0 - cost / null_cost : 0.0;
  out.motion = out.explained >= settings.min_explained;
  if (out.motion) {
    alignWithMotion(&fit, offset, imu_interval, settings, &model, &out);
    return out;
  }
  alignStill(&fit, model, settings, &out);
  return out;
}

std::vector<GyroSample> alignedGyro(const std::vector<GyroSample>& imu, const ImuAlignment& alignment) {
  std::vector<GyroSample> out;
  out.reserve(imu.size());
  const double offset = alignment.offset_observable ? alignment.time_offset : 0.0;
  for (const GyroSample& s : imu) {
    GyroSample corrected;
    corrected.stamp = s.stamp - offset;
    corrected.angular_velocity = (s.angular_velocity - alignment.gyro_bias).cwiseQuotient(alignment.gyro_scale);
    out.push_back(corrected);
  }
  return out;
}

}  // namespace visual_gyro
