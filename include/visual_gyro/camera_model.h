// Pinhole camera with optional lens distortion: pixels <-> unit bearing vectors.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace visual_gyro {

/// Lens distortion models (names as in sensor_msgs/CameraInfo).
enum class DistortionModel {
  kNone,         ///< pinhole, no distortion
  /// "plumb_bob" / radial-tangential, OpenCV's model: k1, k2, p1, p2[, k3[, k4, k5, k6]]; with
  /// eight coefficients the rational model ("rational_polynomial"), whose radial factor is
  /// (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6).
  kPlumbBob,
  kEquidistant,  ///< "equidistant" (fisheye, Kannala-Brandt): k1, k2, k3, k4
};

/// Parses "plumb_bob", "rational_polynomial", "radtan" (EuRoC), "radial-tangential" (all
/// kPlumbBob), "equidistant", "fisheye", "" or "none"; returns false for an unknown name.
bool parseDistortionModel(const std::string& name, DistortionModel* model);

/// Camera intrinsics. Pixel coordinates: origin at the centre of the top-left pixel, u right, v down.
class CameraModel {
 public:
  CameraModel() = default;
  /// fx, fy, cx, cy in pixels; `distortion` coefficients in the model's order.
  CameraModel(double fx, double fy, double cx, double cy, int width, int height,
              DistortionModel model = DistortionModel::kNone,
              const std::vector<double>& distortion = {});

  /// "" when usable, else why not (non-finite or non-positive focal lengths, wrong number of
  /// distortion coefficients, non-finite values, non-positive image size).
  std::string validate() const;

  /// Unit bearing b = normalize(K^-1 [u v 1]) after removing distortion (iterative). Optical frame.
  Eigen::Vector3d bearing(double u, double v) const;
  /// Pixel of a bearing (z > 0), with distortion applied. Inverse of bearing().
  Eigen::Vector2d project(const Eigen::Vector3d& bearing) const;

  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  int width() const { return width_; }
  int height() const { return height_; }
  DistortionModel distortionModel() const { return model_; }
  const std::vector<double>& distortion() const { return distortion_; }

 private:
  double fx_ = 0, fy_ = 0, cx_ = 0, cy_ = 0;
  int width_ = 0, height_ = 0;
  DistortionModel model_ = DistortionModel::kNone;
  std::vector<double> distortion_;
};

/// "" when the calibration is plausible for its image, else what is implausible, with the numbers.
/// Checks, beyond CameraModel::validate():
/// - the principal point lies within the central 60 % of the image in each axis (lens centres lie
///   within a few percent of the image centre);
/// - each focal length is between 0.1 and 100 times the larger image side (fields of view of
///   about 157 deg down to 0.6 deg) and fy / fx is within [0.25, 4];
/// - the distortion is monotonic over the image: along rays from the principal point, the
///   distorted radius keeps growing with the angle to the optical axis until the ray leaves the
///   image (a lens model that folds back would map two directions onto one pixel);
/// - the distortion keeps the field of view plausible for its model, judged at the image's four
///   corners and four edge midpoints after undistortion: undistortion reproduces each of them
///   within 0.01 px; none lies at less than 0.8 times the undistorted pinhole's angle from the
///   optical axis; plumb_bob: none at more than 2 times it, and at most 150 deg between opposite
///   corners; equidistant: none beyond 100 deg from the axis (a 200 deg field of view) or at more
///   than 1.6 times the ideal fisheye's angle (theta = normalised radius).
/// A calibration that fails any of these gives rates that are wrong (KITTI frames with plumb_bob
/// k1 = 5 gave the rate's sign flipped), so it is refused wherever a camera model enters the
/// pipeline (VisualGyro, the nodelet's camera_info, evaluate's readers).
std::string calibrationProblem(const CameraModel& camera);

}  // namespace visual_gyro
