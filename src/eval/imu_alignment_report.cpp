#include "imu_alignment_report.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <vector>

#include "json_writer.h"
#include "visual_gyro/geometry.h"

namespace visual_gyro {
namespace eval {
namespace {

std::string fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

std::string triple(const Eigen::Vector3d& v, int decimals) {
  return fixed(v.x(), decimals) + " " + fixed(v.y(), decimals) + " " + fixed(v.z(), decimals);
}

std::vector<double> list(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

/// The quaternion with w >= 0 (x, y, z, w).
std::vector<double> quaternionList(const Eigen::Quaterniond& q) {
  const double sign = q.w() < 0.0 ? -1.0 : 1.0;
  return {sign * q.x(), sign * q.y(), sign * q.z(), sign * q.w()};
}

bool rotationUsable(const ImuAlignment& a) {
  return a.rotation == RotationObservability::kFull || a.rotation == RotationObservability::kKnown;
}

std::string notesText(const ImuAlignment& a) {
  std::string text;
  for (const std::string& note : a.notes) text += (text.empty() ? "" : "; ") + note;
  return text;
}

}  // namespace

double referenceRotationErrorDeg(const ImuAlignment& a, const AlignmentSource& source) {
  if (!source.has_reference_rotation || a.rotation != RotationObservability::kFull)
    return std::numeric_limits<double>::quiet_NaN();
  return rotationAngleBetween(a.imu_from_camera.toRotationMatrix(), source.reference_rotation) * kRadToDeg;
}

std::string alignmentText(const ImuAlignment& a, const AlignmentSource& source) {
  std::ostringstream out;
  out << "== calibrate_imu on " << source.dataset << ": " << source.images << " images, " << a.frames
      << " frame intervals, " << a.frames_valid << " valid, " << a.frames_used << " used (inside the IMU's span)\n";
  out << "   IMU             " << a.imu_samples << " samples at " << fixed(a.imu_rate_hz, 1) << " Hz, white noise "
      << fixed(a.gyro_noise, 5) << " rad/s per sample\n";
  out << "   motion          the camera's rates explain " << fixed(100.0 * std::max(a.explained, 0.0), 1)
      << " % of the IMU's rate variation" << (a.motion ? "" : ": no rotation seen") << "\n";
  out << "   time offset     ";
  if (a.offset_observable) {
    out << fixed(a.time_offset * 1e3, 3) << " ms +- " << fixed(a.time_offset_sigma * 1e3, 3)
        << " ms (t_imu = t_camera + offset)\n";
  } else {
    out << "not observable\n";
  }
  const Eigen::Vector3d ypr = yawPitchRollFromRotation(a.imu_from_camera.toRotationMatrix()) * kRadToDeg;
  const std::vector<double> q = quaternionList(a.imu_from_camera);
  out << "   rotation        ";
  if (rotationUsable(a)) {
    out << "IMU <- camera quaternion (x y z w) " << fixed(q[0], 6) << " " << fixed(q[1], 6) << " " << fixed(q[2], 6)
        << " " << fixed(q[3], 6);
    if (a.rotation == RotationObservability::kKnown) {
      out << " (given, not estimated)\n";
    } else {
      out << " +- " << fixed(a.rotation_sigma_deg, 3) << " deg (yaw " << fixed(ypr.x(), 2) << ", pitch "
          << fixed(ypr.y(), 2) << ", roll " << fixed(ypr.z(), 2) << " deg)\n";
    }
  } else if (a.rotation == RotationObservability::kAxisOnly) {
    out << "about one axis only: camera axis " << triple(a.rotation_axis_camera, 4) << " = IMU axis "
        << triple(a.rotation_axis_imu, 4) << "\n";
  } else {
    out << "not observable\n";
  }
  const double reference = referenceRotationErrorDeg(a, source);
  if (std::isfinite(reference)) {
    out << "                   " << fixed(reference, 3)
        << " deg from the data's own (EuRoC T_BS, or the bag's /tf_static)\n";
  }
  out << "   gyro bias       " << triple(a.gyro_bias, 5) << " rad/s (IMU frame) +- " << triple(a.gyro_bias_sigma, 5)
      << "\n";
  if (a.has_scale && a.motion)
    out << "   gyro scale      " << triple(a.gyro_scale, 5) << " +- " << triple(a.gyro_scale_sigma, 5) << "\n";
  out << "   rate RMSE       " << fixed(a.rate_rmse * kRadToDeg, 3)
      << " deg/s (visual rate against the aligned, de-biased IMU)\n";
  for (const std::string& note : a.notes) out << "   note            " << note << "\n";
  return out.str();
}

std::string alignmentSnippets(const ImuAlignment& a, const AlignmentSource& source) {
  std::ostringstream out;
  out << "# --- the visual_gyro node's parameter (config/visual_gyro.yaml, or <param> in the launch file) ---\n";
  if (a.offset_observable) {
    char buf[128];
    std::snprintf(buf, sizeof(buf), "time_offset: %.6f   # [s] t_imu = t_camera + time_offset (+- %.6f s)\n",
                  a.time_offset, a.time_offset_sigma);
    out << buf;
  } else {
    out << "# time_offset: not observable from this recording (rotate the camera about all axes, faster)\n";
  }
  const std::vector<double> q = quaternionList(a.imu_from_camera);
  out << "# --- launch file: the camera's rotation in the IMU frame (translation not estimated: measure it) ---\n";
  if (a.rotation == RotationObservability::kFull) {
    char buf[512];
    std::snprintf(buf, sizeof(buf),
                  "<node pkg=\"tf2_ros\" type=\"static_transform_publisher\" name=\"imu_to_camera\"\n"
                  "      args=\"0 0 0 %.6f %.6f %.6f %.6f %s %s\"/>\n",
                  q[0], q[1], q[2], q[3], source.imu_frame.c_str(), source.camera_frame.c_str());
    out << buf;
  } else {
    out << "<!-- camera-IMU rotation not observable from this recording"
        << (a.rotation == RotationObservability::kKnown ? " (it was given)" : "") << " -->\n";
  }
  out << "# --- the IMU's gyro bias [rad/s], IMU frame: subtract it from the IMU's angular_velocity, or start "
         "the filter's bias state there ---\n";
  char buf[160];
  std::snprintf(buf, sizeof(buf), "gyro_bias: [%.6f, %.6f, %.6f]\n", a.gyro_bias.x(), a.gyro_bias.y(),
                a.gyro_bias.z());
  out << buf;
  return out.str();
}

void addAlignmentSummary(const ImuAlignment* a, JsonObject* json) {
  if (a != nullptr && a->offset_observable) {
    json->add("time_offset_ms", a->time_offset * 1e3);
  } else {
    json->addNull("time_offset_ms");
  }
  if (a != nullptr) {
    json->add("gyro_bias_rad_s", list(a->gyro_bias));
  } else {
    json->addNull("gyro_bias_rad_s");
  }
}

void addAlignmentFields(const ImuAlignment& a, const AlignmentSource& source, JsonObject* json) {
  json->add("dataset", source.dataset)
      .add("images", source.images)
      .add("frames", a.frames)
      .add("frames_valid", a.frames_valid)
      .add("frames_used", a.frames_used)
      .add("imu_samples", a.imu_samples)
      .add("imu_rate_hz", a.imu_rate_hz)
      .add("gyro_noise_rad_s", a.gyro_noise)
      .add("explained", a.explained);
  addAlignmentSummary(&a, json);
  if (a.offset_observable) {
    json->add("time_offset_sigma_ms", a.time_offset_sigma * 1e3);
  } else {
    json->addNull("time_offset_sigma_ms");
  }
  json->add("rotation_observable", rotationObservabilityName(a.rotation));
  if (rotationUsable(a)) {
    json->add("rotation_imu_from_camera", quaternionList(a.imu_from_camera));
  } else {
    json->addNull("rotation_imu_from_camera");
  }
  if (a.rotation == RotationObservability::kFull) {
    json->add("rotation_sigma_deg", a.rotation_sigma_deg);
  } else {
    json->addNull("rotation_sigma_deg");
  }
  if (a.rotation == RotationObservability::kAxisOnly) {
    json->add("rotation_axis_camera", list(a.rotation_axis_camera)).add("rotation_axis_imu", list(a.rotation_axis_imu));
  } else {
    json->addNull("rotation_axis_camera").addNull("rotation_axis_imu");
  }
  json->add("reference_rotation_error_deg", referenceRotationErrorDeg(a, source));
  json->add("gyro_bias_sigma_rad_s", list(a.gyro_bias_sigma));
  if (a.has_scale && a.motion) {
    json->add("gyro_scale", list(a.gyro_scale)).add("gyro_scale_sigma", list(a.gyro_scale_sigma));
  } else {
    json->addNull("gyro_scale").addNull("gyro_scale_sigma");
  }
  json->add("rate_rmse_dps", a.rate_rmse * kRadToDeg).add("notes", notesText(a));
}

}  // namespace eval
}  // namespace visual_gyro
