// The accuracy metrics' NEES: it judges the estimate's covariance plus the truth's own error
// (FrameTruth::sigma_rad, per camera axis), and only against pose truth.
#include <gtest/gtest.h>

#include <cmath>

#include "metrics.h"
#include "visual_gyro/geometry.h"

namespace visual_gyro {
namespace {

TEST(Metrics, NeesAddsTheTruthsOwnErrorToTheCovariance) {
  const Eigen::Vector3d error(0.001, -0.002, 0.0005);  // rad, rotation vector of R_est^T R_true
  metrics::FrameEstimate estimate;
  estimate.valid = true;
  estimate.dt = 0.1;
  estimate.rotation = Eigen::Matrix3d::Identity();
  estimate.has_covariance = true;
  const double sigma_estimate = 0.0008;                           // rad per axis
  const Eigen::Vector3d sigma_truth(0.0006, 0.0015, 0.0002);  // rad, about camera x, y, z
  estimate.covariance = sigma_estimate * sigma_estimate * Eigen::Matrix3d::Identity();
  metrics::FrameTruth truth;
  truth.has_rotation = truth.from_poses = true;
  truth.rotation = so3Exp(error);

  const metrics::FrameErrors exact = metrics::scoreFrame(estimate, truth);
  EXPECT_NEAR(exact.nees, error.squaredNorm() / (sigma_estimate * sigma_estimate), 1e-6);
  truth.sigma_rad = sigma_truth;
  const metrics::FrameErrors with_truth_error = metrics::scoreFrame(estimate, truth);
  double expected = 0.0;
  for (int k = 0; k < 3; ++k)
    expected += error[k] * error[k] / (sigma_estimate * sigma_estimate + sigma_truth[k] * sigma_truth[k]);
  EXPECT_NEAR(with_truth_error.nees, expected, 1e-6);
  EXPECT_LT(with_truth_error.nees, exact.nees);
  EXPECT_NEAR(with_truth_error.rotation_error_deg, exact.rotation_error_deg, 1e-12);  // errors unchanged

  // A gyro reference (biased) judges no covariance.
  truth.from_poses = false;
  EXPECT_TRUE(std::isnan(metrics::scoreFrame(estimate, truth).nees));
}

}  // namespace
}  // namespace visual_gyro
