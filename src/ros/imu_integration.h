// How a fusion filter sees the published angular velocity: the ~imu rates integrated piecewise
// constant from each message's stamp to the next one, compared over time with the ground truth.
// Used to choose the stamp of the outputs (current image or midpoint of the two images).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace visual_gyro {
namespace imu_integration {

/// One angular velocity message: stamp [s] and rate [rad/s] in the camera frame.
struct RateSample {
  double stamp = 0.0;
  Eigen::Vector3d rate = Eigen::Vector3d::Zero();
};

/// One ground-truth orientation: stamp [s], camera -> world.
struct TruthSample {
  double stamp = 0.0;
  Eigen::Matrix3d orientation = Eigen::Matrix3d::Identity();
};

/// Orientation error at one time.
struct ErrorPoint {
  double time = 0.0;       ///< [s] since the first truth sample
  double error_deg = 0.0;  ///< angle of R_integrated^T R_true [deg]
};

/// The error series and its summary.
struct IntegrationError {
  std::vector<ErrorPoint> series;  ///< at every `step` from the first to the last truth sample
  double rms_deg = 0.0, max_deg = 0.0, mean_deg = 0.0, final_deg = 0.0;
};

/// Integrates `rates` the way a filter does that treats each message as the instantaneous rate
/// from its stamp until the next message's (zero before the first; the last one holds to the end),
/// starting from the identity at the first truth sample, and compares the result with the truth
/// (R_truth(t0)^T R_truth(t), slerp between samples) every `step` seconds [s]. Both sequences must
/// be sorted by stamp; throws std::invalid_argument when `truth` has fewer than two samples or
/// step is not positive.
IntegrationError integrationError(const std::vector<RateSample>& rates, const std::vector<TruthSample>& truth,
                                  double step);

}  // namespace imu_integration
}  // namespace visual_gyro
