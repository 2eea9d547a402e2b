// Integration test of the visual_gyro node and nodelet (the same source runs against both:
// visual_gyro_node.test and visual_gyro_nodelet.test, and with ~output_frame set and a static
// transform to a body frame: visual_gyro_output_frame.test). Publishes rendered frames with a known
// rotation through image_transport + camera_info and checks what comes out. Every wait is bounded.
//
// The tests share one running node and run in order; each starts its stamps far after the previous
// test's, so the node's gap reset (~max_gap) separates them.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseStamped.h>
#include <image_transport/image_transport.h>
#include <opencv2/imgproc.hpp>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/image_encodings.h>
#include <tf2_ros/static_transform_broadcaster.h>

#include "ros_conversions.h"
#include "ros_test_support.h"
#include "visual_gyro/RotationEstimate.h"
#include "visual_gyro/renderer.h"
#include "visual_gyro/rotation_estimator.h"

namespace {

using visual_gyro::RotationEstimate;
using visual_gyro::ros_test::waitFor;
namespace conv = visual_gyro::ros_conversions;
namespace vgt = visual_gyro::ros_test;
constexpr double kDeg = M_PI / 180.0;

std::string g_output_ns = "/visual_gyro";
std::string g_image_topic = "/test_camera/image_raw";
const char* kCameraFrame = "test_camera_optical";
/// ~output_frame of the node under test ("" = the camera frame) and the rotation output <- camera.
std::string g_output_frame;
/// ~time_offset of the node under test [s]: every output stamp is the image's plus this.
double g_time_offset = 0.0;
Eigen::Matrix3d g_to_output = Eigen::Matrix3d::Identity();

// The backend the node must report: CUDA exactly where this machine's CUDA backend works (the test
// runs on the same machine as the node under test), else the CPU fallback.
std::string expectedBackend() {
  static const std::string backend = visual_gyro::cudaBackendUsable() ? "cuda" : "cpu";
  return backend;
}

std::string expectedFrame() { return g_output_frame.empty() ? std::string(kCameraFrame) : g_output_frame; }
/// A rotation R of the camera expressed in the output frame: T R T^T.
Eigen::Matrix3d inOutput(const Eigen::Matrix3d& r) { return g_to_output * r * g_to_output.transpose(); }

/// The shared publisher and the recorder of the node's outputs.
class Harness : public vgt::OutputRecorder {
 public:
  Harness() : OutputRecorder(g_output_ns), it_(nh_) {
    camera_pub_ = it_.advertiseCamera(g_image_topic, 5);
    info_ = vgt::cameraInfo(vgt::handheldScene(), kCameraFrame);
  }

  int imageSubscribers() const { return static_cast<int>(camera_pub_.getNumSubscribers()); }

  /// Publishes one frame; true when the node answered (one ~orientation per processed frame)
  /// within `timeout` seconds.
  bool send(const cv::Mat& image, const std::string& encoding, double stamp, double timeout = 10.0) {
    const sensor_msgs::Image msg = vgt::imageMsg(image, encoding, stamp, kCameraFrame);
    sensor_msgs::CameraInfo info = info_;
    info.header.stamp = msg.header.stamp;
    const int before = orientations();
    camera_pub_.publish(msg, info);
    return waitFor([&] { return orientations() > before; }, timeout);
  }
  bool sendGray(const cv::Mat& gray, double stamp, double timeout = 10.0) {
    return send(gray, sensor_msgs::image_encodings::MONO8, stamp, timeout);
  }

  /// Waits until the node subscribed to the images (lazy subscription).
  bool waitSubscribed(double timeout = 15.0) {
    if (!waitFor([&] { return imageSubscribers() > 0; }, timeout)) return false;
    ros::WallDuration(0.3).sleep();  // let the camera_info connection settle too
    return true;
  }

 private:
  image_transport::ImageTransport it_;
  image_transport::CameraPublisher camera_pub_;
  sensor_msgs::CameraInfo info_;
};

Harness* g_harness = nullptr;

/// Rendered views of a right turn, 1 degree per frame.
const std::vector<cv::Mat>& turnImages() { return vgt::turnViews(); }

bool outputAdvertised() {
  ros::master::V_TopicInfo topics;
  if (!ros::master::getTopics(topics)) return false;
  for (const auto& t : topics)
    if (t.name == g_output_ns + "/imu") return true;
  return false;
}

/// The estimate whose current image has this stamp (its header carries the midpoint by default).
const RotationEstimate* findRotation(const std::vector<RotationEstimate>& v, double image_stamp) {
  for (const auto& m : v)
    if (std::abs(m.previous_stamp.toSec() - g_time_offset + m.dt - image_stamp) < 1e-6) return &m;
  return nullptr;
}

/// The estimate published with this header stamp (as its Imu).
const RotationEstimate* findRotationByHeader(const std::vector<RotationEstimate>& v, double stamp) {
  for (const auto& m : v)
    if (std::abs(m.header.stamp.toSec() - stamp) < 1e-6) return &m;
  return nullptr;
}

// Must run first: nothing subscribes to the outputs yet.
TEST(VisualGyroRos, SubscribesToImagesOnlyWhileOutputsHaveSubscribers) {
  Harness& h = *g_harness;
  ASSERT_TRUE(waitFor(outputAdvertised, 30.0)) << g_output_ns << "/imu was never advertised: is the node running?";
  ros::WallDuration(1.0).sleep();
  EXPECT_EQ(h.imageSubscribers(), 0) << "the node subscribed to the images with no output subscriber";

  h.subscribeOutputs();
  EXPECT_TRUE(waitFor([&] { return h.imageSubscribers() > 0; }, 15.0))
      << "no image subscription after subscribing to the outputs";
  h.unsubscribeOutputs();
  EXPECT_TRUE(waitFor([&] { return h.imageSubscribers() == 0; }, 15.0))
      << "the image subscription stayed after the last output subscriber left";

  // A single output is enough.
  ros::NodeHandle nh;
  const boost::function<void(const sensor_msgs::ImuConstPtr&)> ignore = [](const sensor_msgs::ImuConstPtr&) {};
  ros::Subscriber only_imu = nh.subscribe<sensor_msgs::Imu>(g_output_ns + "/imu", 1, ignore);
  EXPECT_TRUE(waitFor([&] { return h.imageSubscribers() > 0; }, 15.0));
  only_imu.shutdown();
  EXPECT_TRUE(waitFor([&] { return h.imageSubscribers() == 0; }, 15.0));
}

TEST(VisualGyroRos, RightTurnGivesPositiveYawRateWithCovariances) {
  Harness& h = *g_harness;
  h.subscribeOutputs();
  ASSERT_TRUE(h.waitSubscribed()) << "the node did not subscribe to " << g_image_topic;
  h.clear();
  const auto& images = turnImages();
  const double t0 = 100.0, dt = 0.1;
  for (size_t k = 0; k < images.size(); ++k)
    ASSERT_TRUE(h.sendGray(images[k], t0 + k * dt)) << "no answer to frame " << k;
  h.settle();

  const auto rotations = h.rotations();
  const auto imus = h.imus();
  ASSERT_EQ(rotations.size(), images.size() - 1) << "one RotationEstimate per frame after the first";
  const Eigen::Matrix3d r_true = vgt::yawRight(1.0);  // R_{k-1}^T R_k
  const Eigen::Vector3d omega_true(0.0, 1.0 * kDeg / dt, 0.0);
  for (size_t k = 1; k < images.size(); ++k) {
    SCOPED_TRACE("frame " + std::to_string(k));
    const RotationEstimate* m = findRotation(rotations, t0 + k * dt);
    ASSERT_NE(m, nullptr);
    EXPECT_TRUE(m->valid) << m->status;
    EXPECT_EQ(m->header.frame_id, expectedFrame());
    EXPECT_NEAR(m->previous_stamp.toSec(), t0 + (k - 1) * dt + g_time_offset, 1e-6);
    EXPECT_NEAR(m->dt, dt, 1e-6);
    EXPECT_NEAR(m->header.stamp.toSec(), t0 + (k - 0.5) * dt + g_time_offset, 1e-6)
        << "default stamps: the images' midpoint (+ ~time_offset)";
    EXPECT_NEAR(m->yaw / kDeg, 1.0, 0.15) << "a right turn is a positive yaw";
    EXPECT_NEAR(m->pitch / kDeg, 0.0, 0.15);
    EXPECT_NEAR(m->roll / kDeg, 0.0, 0.15);
    const Eigen::Matrix3d r = conv::fromMsg(m->rotation).toRotationMatrix();
    EXPECT_LT(visual_gyro::rotationAngleBetween(r, inOutput(r_true)) / kDeg, 0.15);
    const Eigen::Vector3d omega(m->angular_velocity.x, m->angular_velocity.y, m->angular_velocity.z);
    const Eigen::Vector3d omega_expected = g_to_output * omega_true;
    EXPECT_LT((omega - omega_expected).norm(), 0.03)
        << "omega " << omega.transpose() << " expected " << omega_expected.transpose();
    if (g_output_frame.empty()) {
      EXPECT_GT(m->angular_velocity.y, 0.0) << "a right turn turns about the optical frame's +y (down)";
    } else {
      EXPECT_LT(m->angular_velocity.z, 0.0) << "a right turn turns about the body frame's -z (REP 103, z up)";
    }
    for (int i = 0; i < 3; ++i) {
      EXPECT_GT(m->angular_velocity_covariance[4 * i], 0.0);
      EXPECT_GT(m->rotation_covariance[4 * i], 0.0);
      for (int j = 0; j < 3; ++j) {
        EXPECT_NEAR(m->angular_velocity_covariance[3 * i + j], m->angular_velocity_covariance[3 * j + i], 1e-12);
        EXPECT_NEAR(m->angular_velocity_covariance[3 * i + j], m->rotation_covariance[3 * i + j] / (dt * dt),
                    1e-9 + 1e-6 * std::abs(m->angular_velocity_covariance[3 * i + j]));
      }
    }
    EXPECT_GT(m->features, 0u);
    EXPECT_GE(m->matches, 8u);
    EXPECT_GT(m->hypotheses, 0u);
    EXPECT_GT(m->winning_votes, 0u);
    // Requested auto (node) or cuda (nodelet): either way the backend that really voted.
    EXPECT_EQ(m->backend, expectedBackend());
    EXPECT_FALSE(m->method.empty());
    EXPECT_GT(m->total_ms, 0.0);
    EXPECT_GE(m->latency_ms, m->total_ms * 0.5);
  }

  ASSERT_EQ(imus.size(), rotations.size()) << "one Imu per valid estimate";
  for (const auto& imu : imus) {
    const RotationEstimate* m = findRotationByHeader(rotations, imu.header.stamp.toSec());
    ASSERT_NE(m, nullptr) << "Imu stamp " << imu.header.stamp << " matches no RotationEstimate";
    EXPECT_EQ(imu.header.frame_id, expectedFrame());
    EXPECT_EQ(imu.orientation_covariance[0], -1.0) << "REP 145: no orientation";
    EXPECT_EQ(imu.linear_acceleration_covariance[0], -1.0) << "REP 145: no linear acceleration";
    EXPECT_DOUBLE_EQ(imu.angular_velocity.x, m->angular_velocity.x);
    EXPECT_DOUBLE_EQ(imu.angular_velocity.y, m->angular_velocity.y);
    EXPECT_DOUBLE_EQ(imu.angular_velocity.z, m->angular_velocity.z);
    for (int i = 0; i < 9; ++i) EXPECT_DOUBLE_EQ(imu.angular_velocity_covariance[i], m->angular_velocity_covariance[i]);
  }

  // The integrated orientation turned right by 1 degree per frame.
  const auto poses = h.orientationMsgs();
  ASSERT_EQ(poses.size(), images.size());
  EXPECT_EQ(poses.back().header.frame_id, "visual_gyro_world");
  for (size_t k = 0; k < poses.size(); ++k)
    EXPECT_NEAR(poses[k].header.stamp.toSec(), t0 + k * dt + g_time_offset, 1e-6)
        << "the image's stamp (+ ~time_offset)";
  const Eigen::Matrix3d integrated = conv::fromMsg(poses.back().pose.orientation).toRotationMatrix();
  EXPECT_LT(visual_gyro::rotationAngleBetween(integrated, inOutput(vgt::yawRight(images.size() - 1.0))) / kDeg, 0.5);
  EXPECT_LT(visual_gyro::rotationAngleBetween(conv::fromMsg(poses.front().pose.orientation).toRotationMatrix(),
                                              Eigen::Matrix3d::Identity()), 1e-9);
}

TEST(VisualGyroRos, JumpBackInTimeAndLongGapReset) {
  Harness& h = *g_harness;
  h.subscribeOutputs();
  ASSERT_TRUE(h.waitSubscribed());
  const auto& images = turnImages();
  const double t0 = 200.0;
  ASSERT_TRUE(h.sendGray(images[0], t0));
  ASSERT_TRUE(h.sendGray(images[1], t0 + 0.1));
  ASSERT_TRUE(h.sendGray(images[2], t0 + 0.2));
  h.settle();
  h.clear();

  // Back in time (a looping bag): processed as a first frame, no estimate, orientation restarts.
  const double t_back = t0 - 50.0;
  ASSERT_TRUE(h.sendGray(images[3], t_back)) << "the frame after a jump back must still be processed";
  ASSERT_TRUE(h.sendGray(images[4], t_back + 0.1));
  h.settle();
  auto rotations = h.rotations();
  EXPECT_EQ(findRotation(rotations, t_back), nullptr) << "an estimate across a jump back in time";
  const RotationEstimate* after = findRotation(rotations, t_back + 0.1);
  ASSERT_NE(after, nullptr);
  EXPECT_NEAR(after->previous_stamp.toSec(), t_back + g_time_offset, 1e-6);
  EXPECT_TRUE(after->valid) << after->status;
  EXPECT_NEAR(after->yaw / kDeg, 1.0, 0.15);
  auto poses = h.orientationMsgs();
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_LT(visual_gyro::rotationAngleBetween(conv::fromMsg(poses[0].pose.orientation).toRotationMatrix(),
                                              Eigen::Matrix3d::Identity()), 1e-9)
      << "the integrated orientation did not restart at the reset";

  // A gap over ~max_gap (1 s): reset as well.
  h.clear();
  const double t_gap = t_back + 0.1 + 5.0;
  ASSERT_TRUE(h.sendGray(images[5], t_gap));
  ASSERT_TRUE(h.sendGray(images[6], t_gap + 0.1));
  h.settle();
  rotations = h.rotations();
  EXPECT_EQ(findRotation(rotations, t_gap), nullptr) << "an estimate across a 5 s gap";
  ASSERT_NE(findRotation(rotations, t_gap + 0.1), nullptr);
  EXPECT_NEAR(findRotation(rotations, t_gap + 0.1)->previous_stamp.toSec(), t_gap + g_time_offset, 1e-6);
}

TEST(VisualGyroRos, EqualStampIsSkipped) {
  Harness& h = *g_harness;
  h.subscribeOutputs();
  ASSERT_TRUE(h.waitSubscribed());
  const auto& images = turnImages();
  const double t0 = 300.0;
  ASSERT_TRUE(h.sendGray(images[0], t0));
  ASSERT_TRUE(h.sendGray(images[1], t0 + 0.1));
  h.settle();
  h.clear();
  EXPECT_FALSE(h.sendGray(images[2], t0 + 0.1, 1.5)) << "a frame with the previous frame's stamp was processed";
  ASSERT_TRUE(h.sendGray(images[2], t0 + 0.2));
  h.settle();
  const auto rotations = h.rotations();
  ASSERT_EQ(rotations.size(), 1u);
  EXPECT_NEAR(rotations[0].previous_stamp.toSec(), t0 + 0.1 + g_time_offset, 1e-6);
  EXPECT_NEAR(rotations[0].yaw / kDeg, 1.0, 0.15);
}

TEST(VisualGyroRos, ColourBayerYuvAndSixteenBitEncodingsAreConverted) {
  Harness& h = *g_harness;
  h.subscribeOutputs();
  ASSERT_TRUE(h.waitSubscribed());
  const auto& images = turnImages();
  const double t0 = 400.0;
  h.clear();
  ASSERT_TRUE(h.sendGray(images[0], t0));
  cv::Mat bgr, rgba, mono16;
  cv::cvtColor(images[1], bgr, cv::COLOR_GRAY2BGR);
  cv::cvtColor(images[2], rgba, cv::COLOR_GRAY2RGBA);
  images[3].convertTo(mono16, CV_16U, 16.0);  // a 12-bit camera
  ASSERT_TRUE(h.send(bgr, sensor_msgs::image_encodings::BGR8, t0 + 0.1));
  ASSERT_TRUE(h.send(rgba, sensor_msgs::image_encodings::RGBA8, t0 + 0.2));
  ASSERT_TRUE(h.send(mono16, sensor_msgs::image_encodings::MONO16, t0 + 0.3));
  // A grey scene's Bayer mosaic is the grey image itself; its UYVY frame has chroma 128.
  ASSERT_TRUE(h.send(images[4], sensor_msgs::image_encodings::BAYER_RGGB8, t0 + 0.4));
  cv::Mat uyvy;
  cv::merge(std::vector<cv::Mat>{cv::Mat(images[5].size(), CV_8UC1, cv::Scalar(128)), images[5]}, uyvy);
  ASSERT_TRUE(h.send(uyvy, sensor_msgs::image_encodings::YUV422, t0 + 0.5));
  h.settle();
  const auto rotations = h.rotations();
  ASSERT_EQ(rotations.size(), 5u);
  for (const auto& m : rotations) {
    EXPECT_TRUE(m.valid) << m.status;
    EXPECT_NEAR(m.yaw / kDeg, 1.0, 0.15);
  }
}

TEST(VisualGyroRos, UnsupportedEncodingIsSkippedAndTheNodeKeepsRunning) {
  Harness& h = *g_harness;
  h.subscribeOutputs();
  ASSERT_TRUE(h.waitSubscribed());
  ros::NodeHandle nh;
  std::atomic<bool> diagnosed{false};
  ros::Subscriber diag_sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 10, [&diagnosed](const diagnostic_msgs::DiagnosticArrayConstPtr& a) {
        for (const auto& s : a->status)
          for (const auto& kv : s.values)
            if (kv.key == "Skipped: encoding 32FC1" && kv.value != "0") diagnosed = true;
      });
  const auto& images = turnImages();
  const double t0 = 500.0;
  h.clear();
  ASSERT_TRUE(h.sendGray(images[0], t0));
  cv::Mat float_image;
  images[1].convertTo(float_image, CV_32F, 1.0 / 255.0);
  EXPECT_FALSE(h.send(float_image, sensor_msgs::image_encodings::TYPE_32FC1, t0 + 0.1, 1.5))
      << "a 32FC1 image gave an output";
  // Still running: the next good frame is estimated against the last good one.
  ASSERT_TRUE(h.sendGray(images[2], t0 + 0.2)) << "the node stopped answering after a bad encoding";
  h.settle();
  const auto rotations = h.rotations();
  ASSERT_EQ(rotations.size(), 1u);
  EXPECT_NEAR(rotations[0].previous_stamp.toSec(), t0 + g_time_offset, 1e-6);
  EXPECT_TRUE(rotations[0].valid) << rotations[0].status;
  EXPECT_NEAR(rotations[0].yaw / kDeg, 2.0, 0.2);
  EXPECT_TRUE(waitFor([&] { return diagnosed.load(); }, 5.0))
      << "/diagnostics never reported the skipped 32FC1 frame";
}

}  // namespace

int main(int argc, char** argv) {
  return vgt::runRosTests(argc, argv, "test_visual_gyro_ros", 2, [] {
    ros::NodeHandle pnh("~");
    pnh.param<std::string>("output_ns", g_output_ns, g_output_ns);
    pnh.param<std::string>("image_topic", g_image_topic, g_image_topic);
    pnh.param<std::string>("output_frame", g_output_frame, "");
    pnh.param("time_offset", g_time_offset, 0.0);
    std::unique_ptr<tf2_ros::StaticTransformBroadcaster> static_tf;
    if (!g_output_frame.empty()) {
      // A body frame (REP 103: x forward, y left, z up) of the optical frame (x right, y down, z fwd).
      g_to_output << 0, 0, 1, -1, 0, 0, 0, -1, 0;
      geometry_msgs::TransformStamped t;
      t.header.stamp = ros::Time::now();
      t.header.frame_id = g_output_frame;
      t.child_frame_id = kCameraFrame;
      t.transform.translation.x = 0.2;
      t.transform.rotation = conv::toMsg(Eigen::Quaterniond(g_to_output));
      static_tf.reset(new tf2_ros::StaticTransformBroadcaster());
      static_tf->sendTransform(t);
    }
    Harness harness;
    g_harness = &harness;
    const int result = RUN_ALL_TESTS();
    g_harness = nullptr;
    return result;
  });
}
