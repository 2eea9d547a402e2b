// The nodelet's output messages without a master: an invalid estimate is the identity with a zero
// rate (as the offline evaluation scores it), the Imu policy for invalid estimates, the output
// frame rotation of rates and covariances; and how recorded outputs are scored against a gyro.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>

#include "bag_tools.h"
#include "output_publisher.h"
#include "ros_conversions.h"
#include "visual_gyro/geometry.h"

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
  f.backend = visual_gyro::Backend::kCpu;
  return f;
}

TEST(OutputMessages, ValidEstimateCarriesRotationRateAndCovariance) {
  const FrameResult r = turnResult();
  OutputSettings settings;
  settings.method = "vote";
  const FrameOutput frame = frameOf(r, true);
  const auto msg = om::rotationEstimate(frame, std_msgs::Header(), Eigen::Matrix3d::Identity(), settings);
  EXPECT_TRUE(msg->valid);
  EXPECT_EQ(msg->backend, "cpu");
  EXPECT_EQ(msg->status, "");
  EXPECT_NEAR(msg->dt, 0.1, 1e-12);
  EXPECT_NEAR(msg->yaw, 0.02, 1e-12);
  EXPECT_NEAR(msg->angular_velocity.y, 0.2, 1e-12);
  EXPECT_EQ(msg->method, "vote");
  EXPECT_EQ(msg->matches, 400u);
  EXPECT_EQ(msg->tracked, 150u);
  EXPECT_TRUE(msg->half_resolution);
  const auto imu = om::imu(frame, std_msgs::Header(), Eigen::Matrix3d::Identity(), settings);
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
  const FrameOutput frame = frameOf(r, false);
  const auto msg = om::rotationEstimate(frame, std_msgs::Header(), Eigen::Matrix3d::Identity(), settings);
  EXPECT_FALSE(msg->valid);
  EXPECT_EQ(msg->status, "too_few_matches: 5 (need 8)");
  EXPECT_DOUBLE_EQ(msg->rotation.w, 1.0);
  EXPECT_DOUBLE_EQ(msg->yaw, 0.0);
  EXPECT_DOUBLE_EQ(msg->angular_velocity.y, 0.0);
  settings.publish_invalid = false;
  EXPECT_FALSE(om::imu(frame, std_msgs::Header(), Eigen::Matrix3d::Identity(), settings))
      << "an Imu for an invalid estimate without ~publish_invalid";
  settings.publish_invalid = true;
  settings.invalid_variance = 7.0;
  const auto imu = om::imu(frame, std_msgs::Header(), Eigen::Matrix3d::Identity(), settings);
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

// The Imu is built from the frame's result, not from the RotationEstimate, yet carries exactly the
// estimate's header, rate and rate covariance, in the output frame too.
TEST(OutputMessages, ImuCarriesWhatTheRotationEstimateCarries) {
  FrameResult r = turnResult();
  r.angular_velocity = Eigen::Vector3d(0.13, -0.27, 0.05);
  r.angular_velocity_covariance << 3e-4, 1e-5, -2e-5, 1e-5, 2e-4, 4e-6, -2e-5, 4e-6, 5e-4;
  const Eigen::Matrix3d to_output =
      (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(-1.1, Eigen::Vector3d::UnitZ()))
          .toRotationMatrix();
  std_msgs::Header header;
  header.stamp.fromSec(10.05);
  header.frame_id = "body";
  header.seq = 17;
  const FrameOutput frame = frameOf(r, true);
  const auto msg = om::rotationEstimate(frame, header, to_output, OutputSettings());
  const auto imu = om::imu(frame, header, to_output, OutputSettings());
  ASSERT_TRUE(imu);
  EXPECT_EQ(imu->header.stamp, msg->header.stamp);
  EXPECT_EQ(imu->header.frame_id, msg->header.frame_id);
  EXPECT_EQ(imu->header.seq, msg->header.seq);
  EXPECT_EQ(imu->angular_velocity.x, msg->angular_velocity.x);
  EXPECT_EQ(imu->angular_velocity.y, msg->angular_velocity.y);
  EXPECT_EQ(imu->angular_velocity.z, msg->angular_velocity.z);
  for (int i = 0; i < 9; ++i) EXPECT_EQ(imu->angular_velocity_covariance[i], msg->angular_velocity_covariance[i]) << i;
}

}  // namespace

// A bag whose reference is a gyro (no poses), with a bias and 5 ms late: the recorded estimates
// are scored after the gyro is aligned with them, as evaluate scores, so exact estimates score
// (almost) zero; the raw gyro's bias alone would be 0.06 deg per 50 ms pair.
TEST(EvaluateOutputs, GyroReferenceIsAlignedBeforeScoring) {
  const auto rate = [](double t) {
    return Eigen::Vector3d(0.3 * std::sin(2.0 * M_PI * t), 0.2 * std::cos(3.0 * t), 0.1 * std::sin(5.0 * t));
  };
  const Eigen::Vector3d bias(0.02, -0.01, 0.015);
  const double offset = 0.005;
  visual_gyro::bag_tools::BagContents bag;
  for (int i = 0; i <= 800; ++i) {
    const double t = 10.0 + i / 200.0;
    sensor_msgs::ImuPtr imu(new sensor_msgs::Imu);
    imu->header.stamp.fromSec(t + offset);
    const Eigen::Vector3d w = rate(t) + bias;
    imu->angular_velocity.x = w.x();
    imu->angular_velocity.y = w.y();
    imu->angular_velocity.z = w.z();
    bag.gyro.push_back(imu);
  }
  std::vector<visual_gyro::RotationEstimate> estimates;
  const double dt = 0.05;
  for (double t0 = 10.5; t0 + dt <= 13.5; t0 += dt) {
    Eigen::Matrix3d r = Eigen::Matrix3d::Identity();  // the true rotation over [t0, t0 + dt]
    for (int k = 0; k < 100; ++k) r = r * visual_gyro::so3Exp(rate(t0 + (k + 0.5) * dt / 100) * dt / 100);
    visual_gyro::RotationEstimate e;
    e.previous_stamp.fromSec(t0);
    e.dt = dt;
    e.valid = true;
    e.rotation = visual_gyro::ros_conversions::toMsg(Eigen::Quaterniond(r));
    const Eigen::Vector3d w = visual_gyro::so3Log(r) / dt;
    e.angular_velocity.x = w.x();
    e.angular_velocity.y = w.y();
    e.angular_velocity.z = w.z();
    for (int i = 0; i < 9; ++i) e.angular_velocity_covariance[i] = i % 4 == 0 ? 1e-6 : 0.0;
    estimates.push_back(e);
  }
  const auto s = visual_gyro::bag_tools::evaluateOutputs(estimates, 0, bag, "synthetic");
  ASSERT_TRUE(s.gyro_aligned);
  EXPECT_LT((s.gyro_alignment.gyro_bias - bias).norm(), 1e-3);
  ASSERT_TRUE(s.gyro_alignment.offset_observable);
  EXPECT_NEAR(s.gyro_alignment.time_offset, offset, 5e-4);
  EXPECT_EQ(s.accuracy.with_truth, static_cast<int>(estimates.size()));
  EXPECT_LT(s.accuracy.rot_rmse_deg, 0.005);
  EXPECT_NE(s.json().find("\"gyro_aligned\": true"), std::string::npos) << s.json();
  EXPECT_NE(s.json().find("\"gyro_bias_rad_s\": ["), std::string::npos) << s.json();
}
