// Pinhole camera with optional lens distortion (plumb_bob / radial-tangential with OpenCV's rational
// terms, equidistant).
#include "visual_gyro/camera_model.h"
#include "visual_gyro/geometry.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <iomanip>
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

/// Whether `count` coefficients make a radial-tangential model: k1 k2 p1 p2, k3, or the rational
/// model's k4 k5 k6 as well (OpenCV's lengths of its distortion vector).
bool radTanCount(size_t count) { return count == 4 || count == 5 || count == 8; }

/// Radial-tangential distortion of a normalized point and its 2x2 Jacobian d(xd,yd)/d(x,y). The
/// radial factor is (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6), OpenCV's; the
/// denominator is 1 without k4..k6, so those models' arithmetic is the plain polynomial's.
void distortRadTan(const std::vector<double>& d, double x, double y, double* xd, double* yd,
                   double jac[4]) {
  const double k1 = d[0], k2 = d[1], p1 = d[2], p2 = d[3];
  const double k3 = d.size() > 4 ? d[4] : 0.0;
  const double k4 = d.size() > 7 ? d[5] : 0.0, k5 = d.size() > 7 ? d[6] : 0.0, k6 = d.size() > 7 ? d[7] : 0.0;
  const double x2 = x * x, y2 = y * y, xy = x * y;
  const double r2 = x2 + y2;
  const double denominator = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6));
  const double radial = (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))) / denominator;
  *xd = x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x2);
  *yd = y * radial + p1 * (r2 + 2.0 * y2) + 2.0 * p2 * xy;
  if (jac != nullptr) {
    // d(radial)/d(r2), by the quotient rule.
    const double dradial = (k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2) - radial * (k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2))) /
                           denominator;
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
  } else if (lower == "plumb_bob" || lower == "rational_polynomial" || lower == "radtan" ||
             lower == "radial-tangential" || lower == "radial_tangential") {
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
        if (!radTanCount(n)) {
          why << "plumb_bob distortion needs 4, 5 or 8 coefficients (k1 k2 p1 p2 [k3 [k4 k5 k6]]), got " << n;
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
  if (!radTanCount(distortion_.size())) {
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

namespace {

/// Where the principal point may lie: within the central kPrincipalPointCentralFraction of the
/// image in each axis. The lens centres of calibrated cameras lie within a few percent of the image
/// centre (KITTI 48.9 % / 49.3 %, EuRoC 48.9 % / 51.8 %, TUM-VI's fisheye 49.8 % / 50.2 %, the
/// renderer 50 %); one far from it is a wrong K (another resolution's, transposed, a typo) or
/// a crop far off the optical axis, which the checks cannot tell apart. On kitti_turn a principal
/// point at the image corner gave valid rates up to 50 % too low, on 23 of 50 frames more than three
/// of their standard deviations off.
constexpr double kPrincipalPointCentralFraction = 0.6;

/// Bounds on the angle of an image corner or edge midpoint from the optical axis after
/// undistortion, relative to the angle of the same pixel through the undistorted pinhole
/// (atan of its normalised radius). Lenses shrink the pinhole's field of view by a few percent at
/// most (pincushion distortion of telephoto lenses); kitti_turn's frames with plumb_bob k1 = 5 or
/// equidistant k1 = 3 (corners at 0.58 and 0.69 of the pinhole's angle) gave valid rates of the
/// wrong sign. Barrel distortion widens it: EuRoC's radial-tangential lens by 1.07 to 1.20 over
/// its rim; twice the pinhole's angle is far beyond any lens a plumb_bob fit can describe.
constexpr double kMinAngleRatio = 0.8;
constexpr double kMaxPlumbBobAngleRatio = 2.0;
/// Diagonal field of view of plumb_bob [deg]: its polynomial in the tangent of the angle cannot
/// follow a lens much wider (a tangent of 3.7 at 75 deg); wider lenses need the equidistant model.
constexpr double kMaxPlumbBobDiagonalFovDeg = 150.0;
/// Equidistant (fisheye) lenses: the image's edge midpoints at most 100 deg from the axis (a 200 deg
/// field of view, beyond the 185-195 deg fisheyes of robotics, whose image circle is fitted to the
/// image height or wider); the corners of a circular fisheye's image lie outside its circle, where
/// the model is only extrapolated (TUM-VI's at 115 deg), so they are held to the ratio alone. Every
/// rim point at most kMaxEquidistantAngleRatio times the ideal fisheye's angle (theta = normalised
/// radius): an orthographic fisheye, the most compressed projection in use, reaches 1.45 times it
/// at 98 % of its 90 deg.
constexpr double kMaxEquidistantAngleDeg = 100.0;
constexpr double kMaxEquidistantAngleRatio = 1.6;
/// Undistortion must reproduce the pixel it started from to this [px]: a model whose inverse does
/// not converge gives bearings no lens has.
constexpr double kMaxRoundTripErrorPx = 0.01;

std::string principalPointProblem(const CameraModel& camera) {
  const double w = camera.width(), h = camera.height();
  std::ostringstream why;
  // Pixel centres run from 0 to w - 1; the image's edges are half a pixel further out.
  if (camera.cx() < -0.5 || camera.cx() > w - 0.5 || camera.cy() < -0.5 || camera.cy() > h - 0.5) {
    why << "principal point (" << camera.cx() << ", " << camera.cy() << ") lies outside the "
        << camera.width() << "x" << camera.height() << " image";
    return why.str();
  }
  const double margin = 0.5 * (1.0 - kPrincipalPointCentralFraction);
  const double fu = (camera.cx() + 0.5) / w, fv = (camera.cy() + 0.5) / h;
  if (fu < margin || fu > 1.0 - margin || fv < margin || fv > 1.0 - margin) {
    why << "principal point (" << camera.cx() << ", " << camera.cy() << ") lies at " << std::fixed
        << std::setprecision(1) << 100.0 * fu << " % / " << 100.0 * fv << " % of the " << camera.width()
        << "x" << camera.height() << " image, outside its central " << std::setprecision(0) << 100.0 * kPrincipalPointCentralFraction
        << " % (lens centres lie within a few percent of the image centre): wrong K, or K of "
           "another resolution?";
  }
  return why.str();
}

std::string focalLengthProblem(const CameraModel& camera) {
  const double side = std::max(camera.width(), camera.height());
  std::ostringstream why;
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
  if (aspect < 0.25 || aspect > 4.0) why << "fy / fx = " << aspect << " is implausible (expected 0.25 to 4)";
  return why.str();
}

/// March outwards along rays from the optical axis: the projected point's distance from the
/// principal point (in focal-length units) must grow with the angle until the ray leaves the
/// image. Rays are parametrised by the angle theta to the optical axis so that fisheye models
/// (which go beyond 90 deg) are covered too.
std::string foldProblem(const CameraModel& camera) {
  const double w = camera.width(), h = camera.height();
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
        std::ostringstream why;
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

/// A point on the image's outline with its bearing after undistortion.
struct ImageRim {
  const char* name = "";
  bool corner = false;       ///< a corner (else an edge midpoint)
  Eigen::Vector2d pixel;     ///< on the outer edge of the image [px]
  Eigen::Vector3d bearing;   ///< camera.bearing(pixel)
  double angle = 0.0;        ///< of the bearing from the optical axis [rad]
  double normalized_radius = 0.0;  ///< of the pixel before undistortion (focal-length units)
  double pinhole_angle = 0.0;      ///< atan(normalized_radius): the undistorted pinhole's angle [rad]
  double round_trip_error = 0.0;   ///< |project(bearing) - pixel| [px]
};

/// The four corners and four edge midpoints, clockwise from the top-left corner.
std::vector<ImageRim> imageRim(const CameraModel& camera) {
  const double left = -0.5, right = camera.width() - 0.5, top = -0.5, bottom = camera.height() - 0.5;
  const double mid_u = 0.5 * (left + right), mid_v = 0.5 * (top + bottom);
  const std::vector<std::pair<const char*, Eigen::Vector2d>> points = {
      {"top-left corner", {left, top}},       {"top edge", {mid_u, top}},
      {"top-right corner", {right, top}},     {"right edge", {right, mid_v}},
      {"bottom-right corner", {right, bottom}}, {"bottom edge", {mid_u, bottom}},
      {"bottom-left corner", {left, bottom}}, {"left edge", {left, mid_v}}};
  std::vector<ImageRim> rim;
  for (const auto& point : points) {
    ImageRim r;
    r.name = point.first;
    r.corner = rim.size() % 2 == 0;
    r.pixel = point.second;
    r.bearing = camera.bearing(r.pixel.x(), r.pixel.y());
    r.angle = std::atan2(std::hypot(r.bearing.x(), r.bearing.y()), r.bearing.z());
    const double radius = std::hypot((r.pixel.x() - camera.cx()) / camera.fx(),
                                     (r.pixel.y() - camera.cy()) / camera.fy());
    r.pinhole_angle = std::atan(radius);
    r.normalized_radius = radius;
    r.round_trip_error = (camera.project(r.bearing) - r.pixel).norm();
    rim.push_back(r);
  }
  return rim;
}

std::string fieldOfViewProblem(const CameraModel& camera) {
  const bool fisheye = camera.distortionModel() == DistortionModel::kEquidistant;
  const std::vector<ImageRim> rim = imageRim(camera);
  std::ostringstream why;
  why.precision(3);
  const std::string model = fisheye ? "equidistant" : camera.distortion().size() == 8 ? "rational_polynomial" : "plumb_bob";
  for (const ImageRim& r : rim) {
    if (!r.bearing.allFinite() || !(r.round_trip_error <= kMaxRoundTripErrorPx)) {
      why << "the " << model << " distortion cannot be inverted at the " << r.name << " (pixel "
          << r.pixel.x() << ", " << r.pixel.y() << " comes back " << r.round_trip_error
          << " px away): the coefficients do not describe a lens over this image";
      return why.str();
    }
    const double ratio = r.angle / r.pinhole_angle;
    if (ratio < kMinAngleRatio) {
      why << "the " << model << " distortion shrinks the field of view: the " << r.name << " lies "
          << r.angle * kRadToDeg << " deg from the optical axis, " << ratio
          << " times the undistorted pinhole's " << r.pinhole_angle * kRadToDeg << " deg (at least "
          << kMinAngleRatio << " expected; no lens compresses its field of view like that)";
      return why.str();
    }
    if (fisheye) {
      const double fisheye_ratio = r.angle / r.normalized_radius;
      if ((!r.corner && r.angle > kMaxEquidistantAngleDeg * kDegToRad) ||
          fisheye_ratio > kMaxEquidistantAngleRatio) {
        why << "the equidistant distortion widens the field of view implausibly: the " << r.name
            << " lies " << r.angle * kRadToDeg << " deg from the optical axis, " << fisheye_ratio
            << " times the ideal fisheye's " << r.normalized_radius * kRadToDeg << " deg (at most "
            << kMaxEquidistantAngleDeg << " deg at the edges and " << kMaxEquidistantAngleRatio
            << " times expected)";
        return why.str();
      }
    } else if (ratio > kMaxPlumbBobAngleRatio) {
      why << "the plumb_bob distortion widens the field of view implausibly: the " << r.name << " lies "
          << r.angle * kRadToDeg << " deg from the optical axis, " << ratio
          << " times the undistorted pinhole's " << r.pinhole_angle * kRadToDeg << " deg (at most "
          << kMaxPlumbBobAngleRatio << " expected)";
      return why.str();
    }
  }
  if (!fisheye) {
    // Corners come in the order of imageRim(): 0, 2, 4, 6; diagonals 0-4 and 2-6.
    for (const auto& diagonal : {std::make_pair(0, 4), std::make_pair(2, 6)}) {
      const ImageRim& a = rim[diagonal.first];
      const ImageRim& b = rim[diagonal.second];
      const double fov = std::acos(std::clamp(a.bearing.dot(b.bearing), -1.0, 1.0)) * kRadToDeg;
      if (fov > kMaxPlumbBobDiagonalFovDeg) {
        why << "the plumb_bob distortion gives a diagonal field of view of " << fov << " deg ("
            << a.name << " to " << b.name << "), more than the " << kMaxPlumbBobDiagonalFovDeg
            << " deg a plumb_bob fit can describe (use equidistant for wider lenses)";
        return why.str();
      }
    }
  }
  return "";
}

}  // namespace

std::string calibrationProblem(const CameraModel& camera) {
  const std::string invalid = camera.validate();
  if (!invalid.empty()) return invalid;
  std::string problem = principalPointProblem(camera);
  if (problem.empty()) problem = focalLengthProblem(camera);
  if (!problem.empty()) return problem;
  if (camera.distortionModel() == DistortionModel::kNone || allZero(camera.distortion())) return "";
  problem = foldProblem(camera);
  if (problem.empty()) problem = fieldOfViewProblem(camera);
  return problem;
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
  if (model_ == DistortionModel::kPlumbBob && radTanCount(distortion_.size())) {
    double xd, yd;
    distortRadTan(distortion_, x, y, &xd, &yd, nullptr);
    return Eigen::Vector2d(fx_ * xd + cx_, fy_ * yd + cy_);
  }
  // Wrong coefficient count: validate() names it; never return a silently wrong pixel.
  return Eigen::Vector2d(nan, nan);
}

}  // namespace visual_gyro
