// How a camera-IMU alignment (visual_gyro/imu_alignment.h) is reported: the readable summary, the
// snippets to paste (node parameter, static tf, bias) and the JSON keys, defined once for
// `calibrate_imu` and `evaluate`. Plain C++ and Eigen.
#pragma once

#include <string>

#include <Eigen/Core>

#include "visual_gyro/imu_alignment.h"

namespace visual_gyro {

class JsonObject;

namespace eval {

/// Where the alignment came from, for the summary.
struct AlignmentSource {
  std::string dataset;       ///< folder or bag name
  int images = 0;            ///< images read
  std::string camera_frame;  ///< frame_id of the camera (optical) for the static tf
  std::string imu_frame;     ///< frame_id of the IMU
  /// A rotation IMU <- camera the data came with (EuRoC's T_BS), to compare with.
  bool has_reference_rotation = false;
  Eigen::Matrix3d reference_rotation = Eigen::Matrix3d::Identity();
};

/// Angle [deg] between the estimated rotation and the source's reference; NaN without a
/// reference or a fully observable rotation.
double referenceRotationErrorDeg(const ImuAlignment& alignment, const AlignmentSource& source);

/// The readable summary: counts, each estimate with its uncertainty or why it is not observable.
std::string alignmentText(const ImuAlignment& alignment, const AlignmentSource& source);

/// What to paste: the node's ~time_offset [s] as YAML, a tf2_ros static_transform_publisher line
/// for the launch file (imu_frame -> camera_frame, rotation only) and the bias as YAML; each
/// commented out with the reason when it is not observable.
std::string alignmentSnippets(const ImuAlignment& alignment, const AlignmentSource& source);

/// The keys `evaluate` reports for a gyro reference: time_offset_ms (null when not observable)
/// and gyro_bias_rad_s ([x, y, z], IMU frame); both null when `alignment` is null (no gyro).
void addAlignmentSummary(const ImuAlignment* alignment, JsonObject* json);

/// Every key calibrate_imu's JSON line has (see doc/imu_alignment.md): the summary's keys and the
/// uncertainties, observability, rotation quaternion (x, y, z, w), scale, rate RMSE and notes.
void addAlignmentFields(const ImuAlignment& alignment, const AlignmentSource& source, JsonObject* json);

}  // namespace eval
}  // namespace visual_gyro
