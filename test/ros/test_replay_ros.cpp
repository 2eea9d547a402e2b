// Replay test: a bag made from ../shared/data/kitti_turn (make_bag's code) is played frame by frame
// through the running visual_gyro node (replay_kitti.test); the published rotations must match the
// bag's ground truth (yaw RMSE <= 0.4 deg per frame, issue 2's bound) and the yaw plot must carry
// both the estimate and the ground truth. Skipped with a message when the data is absent.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <mutex>

#include <ros/ros.h>
#include <visualization_msgs/Marker.h>

#include "bag_tools.h"
#include "frame_player.h"
#include "test_support.h"
#include "visual_gyro/sequence.h"

namespace {

namespace bt = visual_gyro::bag_tools;

TEST(VisualGyroReplay, KittiTurnYawMatchesGroundTruth) {
  std::string why;
  const std::string folder = visual_gyro::test::sharedSequence("kitti_turn", &why);
  if (folder.empty()) GTEST_SKIP() << why;

  const std::string dir = visual_gyro::test::makeTempDir("replay");
  const std::string bag_path = dir + "/kitti_turn.bag";
  const visual_gyro::Sequence sequence = visual_gyro::loadSequence(folder);
  bt::BagWriteOptions write_options;
  const bt::BagWriteSummary written = bt::writeSequenceBag(sequence, bag_path, write_options);
  ASSERT_EQ(written.images, 51);
  ASSERT_EQ(written.poses, 51);
  EXPECT_NEAR(written.first_stamp, 1.0, 1e-9) << "KITTI stamps start at 1 s (ROS stamps must be > 0)";
  const bt::BagContents bag = bt::readSequenceBag(bag_path);
  ASSERT_EQ(bag.frames.size(), 51u);
  EXPECT_EQ(bag.frames[0].info->width, 1241u);
  EXPECT_NEAR(bag.frames[1].image->header.stamp.toSec() - bag.frames[0].image->header.stamp.toSec(), 0.1, 1e-9);

  // The yaw plot's last estimate and ground-truth points.
  std::mutex mutex;
  visualization_msgs::Marker last_estimate, last_truth;
  ros::NodeHandle nh;
  ros::Subscriber plot_sub = nh.subscribe<visualization_msgs::Marker>(
      "/visual_gyro/yaw_plot", 100, [&](const visualization_msgs::MarkerConstPtr& m) {
        std::lock_guard<std::mutex> l(mutex);
        (m->ns == "yaw_ground_truth" ? last_truth : last_estimate) = *m;
      });

  visual_gyro::frame_player::PlayerOptions options;
  options.output_ns = "/visual_gyro";
  options.frame_timeout = 20.0;
  const auto report = visual_gyro::frame_player::playFrames(bag, options);
  ASSERT_TRUE(report.ok) << report.error;
  EXPECT_EQ(report.processed, 51);

  const bt::OutputSummary summary = bt::evaluateOutputs(report.rotations, static_cast<int>(report.imus.size()), bag,
                                                        "kitti_turn");
  std::printf("%s\n%s\n", summary.text().c_str(), summary.json().c_str());
  EXPECT_EQ(summary.frames, 50);
  EXPECT_EQ(summary.compared, 50);
  EXPECT_LE(summary.yaw_rmse_deg, 0.4);
  EXPECT_EQ(summary.imu_published, summary.valid_frames);
  EXPECT_GE(summary.valid_frames, 45);
  // The car turns right by about 98 degrees: the rate is positive about the camera's y axis.
  double yaw_sum = 0.0;
  for (const auto& m : report.rotations) yaw_sum += m.yaw;
  EXPECT_NEAR(yaw_sum * 180.0 / M_PI, 97.9, 5.0);

  ros::WallDuration(0.3).sleep();
  std::lock_guard<std::mutex> l(mutex);
  ASSERT_GE(last_estimate.points.size(), 2u) << "no yaw plot of the estimate";
  ASSERT_GE(last_truth.points.size(), 2u) << "no yaw plot of the ground truth (ground_truth topic)";
  EXPECT_EQ(last_estimate.type, visualization_msgs::Marker::LINE_STRIP);
  // Same scale on both lines: their ends agree to within a few degrees of integrated yaw.
  const double yaw_scale = 0.05;  // config/visual_gyro.yaml plot_yaw_scale [m/deg]
  EXPECT_NEAR(last_estimate.points.back().y / yaw_scale, last_truth.points.back().y / yaw_scale, 3.0);
  EXPECT_GT(last_truth.points.back().y / yaw_scale, 90.0);
  std::filesystem::remove_all(dir);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_replay_ros");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  return result;
}
