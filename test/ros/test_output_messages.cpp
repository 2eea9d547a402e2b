// The nodelet's output messages without a master: an invalid estimate is the identity with a zero
// rate (as the offline evaluation scores it), the Imu policy for invalid estimates, the output
// frame rotation of rates and covariances.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "output_publisher.h"
#include "ros_conversions.h"

namespace {

using visual_gyro::FrameOutput;
using visual_gyro::FrameResult;
using visual_gyro::OutputSettings;
namespace om = visual_gyro::output_messages;

FrameResult turnResult() {
  FrameResult r;
  r.status = visual_gyro::FrameStatus::kValid;
  r.rotation.rotation = Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY()).toRotationMatrix();
  r.rotation.yaw = 0.02;
  r.rotation.covariance = Eigen::Matrix3d::Identity() * 1e-6;
  r.dt = 0.1;
  r.angular_velocity = Eigen::Vector3d(0.0, 0.2, 0.0);
  r.angular_velocity_covariance = Eigen::Matrix3d::Identity() * 1e-4;
  r.features = 700;
  r.rotation.matches_used = 400;
  r.tracked = 150;
  r.half_resolution = true;
  return r;
}

FrameOutput frameOf(const FrameResult& r, bool valid) {
  FrameOutput f;
  f.image_header.stamp.fromSec(10.1);
  f.image_header.frame_id = "cam";
  f.had_previous = true;
  f.previous_stamp = 10.0;
  f.result = &r;
  f.valid = valid;
  f.backend = "cpu";
  return f;
}

TEST(OutputMessages, ValidEstimateCarriesRotationRateAndCovariance) {
  const FrameResult r = turnResult();
  OutputSettings settings;
  settings.method = "vote";
  const auto msg = om::rotationEstimate(frameOf(r, true), std_msgs::Header(), Eigen::Matrix3d::Identity(), settings);
  EXPECT_TRUE(msg->valid);
  EXPECT_EQ(msg->status, "");
  EXPECT_NEAR(msg->dt, 0.1, 1e-12);
  EXPECT_NEAR(msg->yaw, 0.02, 1e-12);
  EXPECT_NEAR(msg->angular_velocity.y, 0.2, 1e-12);
  EXPECT_EQ(msg->method, "vote");
  EXPECT_EQ(msg->matches, 400u);
  EXPECT_EQ(msg->tracked, 150u);
  EXPECT_TRUE(msg->half_resolution);
  const auto imu = om::imu(*msg, settings);
  ASSERT_TRUE(imu);
  EXPECT_NEAR(imu->angular_velocity.y, 0.2, 1e-12);
  EXPECT_NEAR(imu->angular_velocity_covariance[4], 1e-4, 1e-12);
  EXPECT_EQ(imu->orientation_covariance[0], -1.0);
}

TEST(OutputMessages, InvalidEstimateIsTheIdentityAndItsImuFollowsThePolicy) {
  FrameResult r = turnResult();  // a rotation left in place, to show that it is not published
  r.status = visual_gyro::FrameStatus::kTooFewMatches;
  r.reason = "5 (need 8)";
  OutputSettings settings;
  const auto msg = om::rotationEstimate(frameOf(r, false), std_msgs::Header(), Eigen::Matrix3d::Identity(), settings);
  EXPECT_FALSE(msg->valid);
  EXPECT_EQ(msg->status, "too_few_matches: 5 (need 8)");
  EXPECT_DOUBLE_EQ(msg->rotation.w, 1.0);
  EXPECT_DOUBLE_EQ(msg->yaw, 0.0);
  EXPECT_DOUBLE_EQ(msg->angular_velocity.y, 0.0);
  settings.publish_invalid = false;
  EXPECT_FALSE(om::imu(*msg, settings)) << "an Imu for an invalid estimate without ~publish_invalid";
  settings.publish_invalid = true;
  settings.invalid_variance = 7.0;
  const auto imu = om::imu(*msg, settings);
  ASSERT_TRUE(imu);
  EXPECT_DOUBLE_EQ(imu->angular_velocity.y, 0.0);
  EXPECT_DOUBLE_EQ(imu->angular_velocity_covariance[0], 7.0);
  EXPECT_DOUBLE_EQ(imu->angular_velocity_covariance[8], 7.0);
}

TEST(OutputMessages, OutputFrameRotatesRateAndCovariance) {
  FrameResult r = turnResult();
  r.angular_velocity_covariance.diagonal() << 1.0, 2.0, 3.0;
  Eigen::Matrix3d to_body;  // REP 103 body (x fwd, y left, z up) <- optical (x right, y down, z fwd)
  to_body << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const auto msg = om::rotationEstimate(frameOf(r, true), std_msgs::Header(), to_body, OutputSettings());
  EXPECT_NEAR(msg->angular_velocity.z, -0.2, 1e-12) << "a right turn is negative about the body's up axis";
  EXPECT_NEAR(msg->angular_velocity_covariance[8], 2.0, 1e-12);
  EXPECT_NEAR(msg->angular_velocity_covariance[0], 3.0, 1e-12);
  EXPECT_NEAR(msg->yaw, 0.02, 1e-12) << "yaw stays about the optical y axis";
}

}  // namespace
