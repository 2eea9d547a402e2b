// Pinhole camera with optional lens distortion (plumb_bob / radial-tangential, equidistant).
#include "visual_gyro/camera_model.h"
#include "visual_gyro/geometry.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <sstream>

namespace visual_gyro {

namespace {

// Convergence tolerance of the iterative undistortion, in normalized image coordinates
// (1e-10 is ~5e-8 px for a 500 px focal length, far below any feature's precision).
constexpr double kUndistortTolerance = 1e-10;
constexpr int kMaxUndistortIterations = 50;

std::string toLower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

bool allZero(const std::vector<double>& values) {
  return std::all_of(values.begin(), values.end(), [](double v) { return v == 0.0; });
}

/// Radial-tangential distortion of a normalized point and its 2x2 Jacobian d(xd,yd)/d(x,y).
void distortRadTan(const std::vector<double>& d, double x, double y, double* xd, double* yd,
                   double jac[4]) {
  const double k1 = d[0], k2 = d[1], p1 = d[2], p2 = d[3];
  const double k3 = d.size() > 4 ? d[4] : 0.0;
  const double x2 = x * x, y2 = y * y, xy = x * y;
  const double r2 = x2 + y2;
  const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
  *xd = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x2);
  *yd = y * radial + p1 * (r2 + 2.0 * y2) + 2.0 * p2 * xy;
  if (jac != nullptr) {
    // d(radial)/d(r2)
    const double dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);
    jac[0] = radial + 2.0 * x2 * dradial + 2.0 * p1 * y + 6.0 * p2 * x;  // dxd/dx
    jac[1] = 2.0 * xy * dradial + 2.0 * p1 * x + 2.0 * p2 * y;           // dxd/dy
    jac[2] = 2.0 * xy * dradial + 2.0 * p1 * x + 2.0 * p2 * y;           // dyd/dx
    jac[3] = radial + 2.0 * y2 * dradial + 6.0 * p1 * y + 2.0 * p2 * x;  // dyd/dy
  }
}

/// Equidistant (Kannala-Brandt) polynomial theta_d(theta) and its derivative.
double equidistantThetaD(const std::vector<double>& d, double theta, double* derivative) {
  const double t2 = theta * theta;
  const double poly = 1.0 + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3])));
  if (derivative != nullptr) {
    *derivative = 1.0 + t2 * (3.0 * d[0] + t2 * (5.0 * d[1] + t2 * (7.0 * d[2] + t2 * 9.0 * d[3])));
  }
  return theta * poly;
}

}  // namespace

bool parseDistortionModel(const std::string& name, DistortionModel* model) {
  const std::string lower = toLower(name);
  DistortionModel parsed;
  if (lower.empty() || lower == "none") {
    parsed = DistortionModel::kNone;
  } else if (lower == "plumb_bob" || lower == "radtan" || lower == "radial-tangential" ||
             lower == "radial_tangential") {
    parsed = DistortionModel::kPlumbBob;
  } else if (lower == "equidistant" || lower == "fisheye") {
    parsed = DistortionModel::kEquidistant;
  } else {
    return false;
  }
  if (model != nullptr) *model = parsed;
  return true;
}

CameraModel::CameraModel(double fx, double fy, double cx, double cy, int width, int height,
                         DistortionModel model, const std::vector<double>& distortion)
    : fx_(fx),
      fy_(fy),
      cx_(cx),
      cy_(cy),
      width_(width),
      height_(height),
      model_(model),
      distortion_(distortion) {}

std::string CameraModel::validate() const {
  std::ostringstream why;
  if (!std::isfinite(fx_) || !std::isfinite(fy_)) {
    why << "focal lengths must be finite (fx = " << fx_ << ", fy = " << fy_ << ")";
  } else if (fx_ <= 0.0 || fy_ <= 0.0) {
    why << "focal lengths must be positive (fx = " << fx_ << ", fy = " << fy_ << ")";
  } else if (!std::isfinite(cx_) || !std::isfinite(cy_)) {
    why << "principal point must be finite (cx = " << cx_ << ", cy = " << cy_ << ")";
  } else if (width_ <= 0 || height_ <= 0) {
    why << "image size must be positive (" << width_ << " x " << height_ << ")";
  } else if (!std::all_of(distortion_.begin(), distortion_.end(),
                          [](double v) { return std::isfinite(v); })) {
    why << "distortion coefficients must be finite";
  } else {
    const size_t n = distortion_.size();
    switch (model_) {
      case DistortionModel::kNone:
        // CameraInfo often carries D = [0 0 0 0 0] with an empty model name: accept zeros.
        if (!allZero(distortion_)) {
          why << "distortion model none but " << n << " non-zero distortion coefficients given";
        }
        break;
      case DistortionModel::kPlumbBob:
        if (n != 4 && n != 5) {
          why << "plumb_bob distortion needs 4 or 5 coefficients (k1 k2 p1 p2 [k3]), got " << n;
        }
        break;
      case DistortionModel::kEquidistant:
        if (n != 4) {
          why << "equidistant distortion needs 4 coefficients (k1 k2 k3 k4), got " << n;
        }
        break;
    }
  }
  return why.str();
}

Eigen::Vector3d CameraModel::bearing(double u, double v) const {
  const double xd = (u - cx_) / fx_;
  const double yd = (v - cy_) / fy_;
  // Zero coefficients (common in CameraInfo) take the pinhole path of kNone.
  if (model_ == DistortionModel::kNone || allZero(distortion_)) {
    return Eigen::Vector3d(xd, yd, 1.0).normalized();
  }
  if (model_ == DistortionModel::kEquidistant) {
    if (distortion_.size() != 4) {
      return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    }
    const double theta_d = std::hypot(xd, yd);
    if (theta_d == 0.0) return Eigen::Vector3d(0.0, 0.0, 1.0);
    // Newton on theta_d(theta) = theta_d, started at theta = theta_d (the undistorted guess).
    double theta = theta_d;
    for (int it = 0; it < kMaxUndistortIterations; ++it) {
      double derivative = 0.0;
      const double residual = equidistantThetaD(distortion_, theta, &derivative) - theta_d;
      if (derivative == 0.0 || !std::isfinite(derivative)) break;
      const double step = residual / derivative;
      theta -= step;
      if (std::abs(step) < kUndistortTolerance) break;
    }
    // Built from sin/cos of theta so that angles near and beyond 90 degrees stay well defined.
    const double s = std::sin(theta) / theta_d;
    return Eigen::Vector3d(s * xd, s * yd, std::cos(theta)).normalized();
  }
  // kPlumbBob
  if (distortion_.size() != 4 && distortion_.size() != 5) {
    return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  }
  // Newton's method on distort(x, y) = (xd, yd), started at the distorted point. Within the image
  // of a real lens the map is a smooth bijection and Newton converges in a handful of steps; a
  // step that increases the residual is halved so that strong distortion cannot make it diverge.
  double x = xd, y = yd;
  double ex, ey, jac[4];
  distortRadTan(distortion_, x, y, &ex, &ey, jac);
  double fx_res = ex - xd, fy_res = ey - yd;
  // Squared norms throughout (they order and threshold alike, without a square root per step;
  // std::hypot's overflow care is not needed at normalised-coordinate scale).
  double residual_norm2 = fx_res * fx_res + fy_res * fy_res;
  // The residual lives in distorted coordinates; stopping well below the tolerance there keeps
  // the undistorted point within kUndistortTolerance as long as the Jacobian is not tiny.
  constexpr double kResidualStop = 1e-3 * kUndistortTolerance;
  for (int it = 0; it < kMaxUndistortIterations && residual_norm2 > kResidualStop * kResidualStop;
       ++it) {
    const double det = jac[0] * jac[3] - jac[1] * jac[2];
    if (det == 0.0 || !std::isfinite(det)) break;
    double dx = (jac[3] * fx_res - jac[1] * fy_res) / det;
    double dy = (-jac[2] * fx_res + jac[0] * fy_res) / det;
    double step_scale = 1.0;
    bool improved = false;
    for (int halving = 0; halving < 30; ++halving) {
      const double nx = x - step_scale * dx, ny = y - step_scale * dy;
      double nex, ney, njac[4];
      distortRadTan(distortion_, nx, ny, &nex, &ney, njac);
      const double nres2 = (nex - xd) * (nex - xd) + (ney - yd) * (ney - yd);
      if (nres2 < residual_norm2) {
        x = nx;
        y = ny;
        fx_res = nex - xd;
        fy_res = ney - yd;
        residual_norm2 = nres2;
        std::copy(njac, njac + 4, jac);
        improved = true;
        break;
      }
      step_scale *= 0.5;
    }
    if (!improved || step_scale * step_scale * (dx * dx + dy * dy) < kUndistortTolerance * kUndistortTolerance) break;
  }
  return Eigen::Vector3d(x, y, 1.0).normalized();
}

std::string calibrationProblem(const CameraModel& camera) {
  const std::string invalid = camera.validate();
  if (!invalid.empty()) return invalid;
  const double w = camera.width(), h = camera.height();
  std::ostringstream why;
  // Pixel centres run from 0 to w - 1; the image's edges are half a pixel further out.
  if (camera.cx() < -0.5 || camera.cx() > w - 0.5 || camera.cy() < -0.5 || camera.cy() > h - 0.5) {
    why << "principal point (" << camera.cx() << ", " << camera.cy() << ") lies outside the "
        << camera.width() << "x" << camera.height() << " image";
    return why.str();
  }
  const double side = std::max(w, h);
  constexpr double kMinFocalPerSide = 0.1, kMaxFocalPerSide = 100.0;
  for (const double f : {camera.fx(), camera.fy()}) {
    if (f < kMinFocalPerSide * side || f > kMaxFocalPerSide * side) {
      why << "focal length " << f << " px is implausible for a " << camera.width() << "x"
          << camera.height() << " image (expected " << kMinFocalPerSide * side << " to "
          << kMaxFocalPerSide * side << " px)";
      return why.str();
    }
  }
  const double aspect = camera.fy() / camera.fx();
  if (aspect < 0.25 || aspect > 4.0) {
    why << "fy / fx = " << aspect << " is implausible (expected 0.25 to 4)";
    return why.str();
  }
  if (camera.distortionModel() == DistortionModel::kNone || allZero(camera.distortion())) return "";

  // March outwards along rays from the optical axis: the projected point's distance from the
  // principal point (in focal-length units) must grow with the angle until the ray leaves the
  // image. Rays are parametrised by the angle theta to the optical axis so that fisheye models
  // (which go beyond 90 deg) are covered too.
  const bool fisheye = camera.distortionModel() == DistortionModel::kEquidistant;
  const double max_theta = (fisheye ? 179.0 : 89.0) * kDegToRad;
  constexpr double kThetaStep = 0.1 * kDegToRad;
  constexpr int kDirections = 72;
  for (int d = 0; d < kDirections; ++d) {
    const double phi = 2.0 * M_PI * d / kDirections;
    double previous_radius = 0.0;
    for (double theta = kThetaStep; theta <= max_theta; theta += kThetaStep) {
      const Eigen::Vector3d ray(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                                std::cos(theta));
      const Eigen::Vector2d pixel = camera.project(ray);
      if (!pixel.allFinite()) break;
      if (pixel.x() < -0.5 || pixel.x() > w - 0.5 || pixel.y() < -0.5 || pixel.y() > h - 0.5) break;
      const double radius = std::hypot((pixel.x() - camera.cx()) / camera.fx(),
                                       (pixel.y() - camera.cy()) / camera.fy());
      if (!(radius > previous_radius)) {
        why << "distortion coefficients fold the image: the distorted radius stops growing at "
            << theta * kRadToDeg << " deg from the optical axis, inside the image (pixel "
            << pixel.x() << ", " << pixel.y() << ")";
        return why.str();
      }
      previous_radius = radius;
    }
  }
  return "";
}

Eigen::Vector2d CameraModel::project(const Eigen::Vector3d& bearing) const {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (model_ == DistortionModel::kEquidistant && distortion_.size() == 4 && !allZero(distortion_)) {
    // The fisheye model is defined by the angle to the optical axis, so it also covers z <= 0.
    const double r = std::hypot(bearing.x(), bearing.y());
    if (r == 0.0) {
      return bearing.z() > 0.0 ? Eigen::Vector2d(cx_, cy_) : Eigen::Vector2d(nan, nan);
    }
    const double theta = std::atan2(r, bearing.z());
    const double theta_d = equidistantThetaD(distortion_, theta, nullptr);
    const double scale = theta_d / r;
    return Eigen::Vector2d(fx_ * scale * bearing.x() + cx_, fy_ * scale * bearing.y() + cy_);
  }
  if (!(bearing.z() > 0.0)) return Eigen::Vector2d(nan, nan);
  const double x = bearing.x() / bearing.z();
  const double y = bearing.y() / bearing.z();
  if (model_ == DistortionModel::kNone || allZero(distortion_)) {
    return Eigen::Vector2d(fx_ * x + cx_, fy_ * y + cy_);
  }
  if (model_ == DistortionModel::kPlumbBob &&
      (distortion_.size() == 4 || distortion_.size() == 5)) {
    double xd, yd;
    distortRadTan(distortion_, x, y, &xd, &yd, nullptr);
    return Eigen::Vector2d(fx_ * xd + cx_, fy_ * yd + cy_);
  }
  // Wrong coefficient count: validate() names it; never return a silently wrong pixel.
  return Eigen::Vector2d(nan, nan);
}

}  // namespace visual_gyro
