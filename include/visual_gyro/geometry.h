// Small rotation geometry shared by the whole package: SO(3) exponential and logarithm, yaw/pitch/
// roll in both directions, angle wrapping, degree/radian factors.
//
// Camera axes: x right, y down, z forward. Yaw is about +y, pitch about +x, roll about +z, and a
// rotation is composed as R = Ry(yaw) Rx(pitch) Rz(roll). Angles in radians unless a name says deg.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace visual_gyro {

constexpr double kPi = 3.14159265358979323846;
/// Multiply degrees by this to get radians.
constexpr double kDegToRad = kPi / 180.0;
/// Multiply radians by this to get degrees.
constexpr double kRadToDeg = 180.0 / kPi;

/// Cross-product matrix: skew(v) * x = v x x.
inline Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

/// SO(3) exponential: the rotation of angle |w| [rad] about w / |w|.
inline Eigen::Matrix3d so3Exp(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  // First order below any angle AngleAxis can normalise the axis of.
  if (angle < 1e-15) return Eigen::Matrix3d::Identity() + skew(w);
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

/// A rolling shutter's row of a unit bearing: its normalised image row y / z (0 at the principal
/// point); 0 for a bearing more than 84 deg off the axis (z <= 0.1), which has no row.
inline double normalisedRow(double y, double z) { return z > 0.1 ? y / z : 0.0; }

/// The row of a match (previous <-> current bearing) in the row-skew model of a rolling shutter
/// (RotationResult's row skew): the mean normalised row of its two bearings. Match i's rotation is
/// R exp(s_i row_skew), R the rotation of the principal point's row.
inline double matchRow(const Eigen::Vector3d& previous, const Eigen::Vector3d& current) {
  return 0.5 * (normalisedRow(previous.y(), previous.z()) + normalisedRow(current.y(), current.z()));
}

/// SO(3) logarithm: the rotation vector (axis * angle [rad], angle in [0, pi]) of R. Goes through
/// the normalised quaternion, which is accurate for small angles too.
inline Eigen::Vector3d so3Log(const Eigen::Matrix3d& rotation) {
  const Eigen::AngleAxisd aa(Eigen::Quaterniond(rotation).normalized());
  return aa.angle() * aa.axis();
}

/// Angle of a rotation [rad], in [0, pi].
inline double rotationAngle(const Eigen::Matrix3d& rotation) {
  return Eigen::AngleAxisd(Eigen::Quaterniond(rotation).normalized()).angle();
}

/// Angle of the rotation a^T b [rad]: how far apart two rotations are.
inline double rotationAngleBetween(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return rotationAngle(a.transpose() * b);
}

/// Takes R = Ry(yaw) Rx(pitch) Rz(roll) apart: (yaw, pitch, roll) [rad], pitch in [-pi/2, pi/2].
inline Eigen::Vector3d yawPitchRollFromRotation(const Eigen::Matrix3d& rotation) {
  const double yaw = std::atan2(rotation(0, 2), rotation(2, 2));
  const double pitch = std::asin(std::clamp(-rotation(1, 2), -1.0, 1.0));
  const double roll = std::atan2(rotation(1, 0), rotation(1, 1));
  return Eigen::Vector3d(yaw, pitch, roll);
}

/// Builds R = Ry(yaw) Rx(pitch) Rz(roll) from angles [rad].
inline Eigen::Matrix3d rotationFromYawPitchRoll(double yaw, double pitch, double roll) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()))
      .toRotationMatrix();
}

/// An angle [deg] wrapped into (-180, 180].
inline double wrapAngleDeg(double angle_deg) {
  if (!std::isfinite(angle_deg)) return angle_deg;
  angle_deg = std::remainder(angle_deg, 360.0);
  return angle_deg <= -180.0 ? angle_deg + 360.0 : angle_deg;
}

/// `angle_deg` moved by whole turns to lie within 180 deg of `reference_deg` (continuous plots).
inline double unwrapAngleDeg(double angle_deg, double reference_deg) {
  return reference_deg + wrapAngleDeg(angle_deg - reference_deg);
}

}  // namespace visual_gyro
