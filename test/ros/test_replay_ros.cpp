// Replay test: a bag made from ../shared/data/kitti_turn (make_bag's code) is played frame by frame
// through the running visual_gyro node (replay_kitti.test); the published rotations must match the
// bag's ground truth (yaw RMSE <= 0.4 deg per frame, the paper method's accuracy bound), the outputs are stamped at
// the midpoint of their two images, and the yaw plot must carry both the estimate and the ground
// truth, readable through its axis labels. The same bag JPEG-compressed (quality 90) goes through a
// second nodelet that reads <image>/compressed. Skipped with a message when the data is absent.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <mutex>

#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include "bag_tools.h"
#include "frame_player.h"
#include "ros_test_support.h"
#include "test_support.h"
#include "visual_gyro/sequence.h"

namespace {

namespace bt = visual_gyro::bag_tools;

const visualization_msgs::Marker* findMarker(const visualization_msgs::MarkerArray& array, const std::string& ns) {
  for (const auto& m : array.markers)
    if (m.ns == ns) return &m;
  return nullptr;
}

/// Reads a height of the yaw panel off the plot the way a person does: through the numeric tick
/// labels left of the time axis' start (x < `axis_x`) at y >= 0 (the yaw panel; the rate panel lies
/// below), by a straight line through them. NaN when fewer than two labels are found.
double readYawOffPlot(const visualization_msgs::MarkerArray& array, double axis_x, double y) {
  std::vector<std::pair<double, double>> ticks;  // (y, value)
  for (const auto& m : array.markers) {
    if (m.type != visualization_msgs::Marker::TEXT_VIEW_FACING || m.ns != "labels") continue;
    if (m.pose.position.x >= axis_x || m.pose.position.y < -1e-6) continue;
    char* end = nullptr;
    const double value = std::strtod(m.text.c_str(), &end);
    if (end != m.text.c_str() && *end == '\0') ticks.emplace_back(m.pose.position.y, value);
  }
  if (ticks.size() < 2) return NAN;
  const auto& a = ticks.front();
  const auto& b = ticks.back();
  if (a.first == b.first) return NAN;
  return a.second + (y - a.first) * (b.second - a.second) / (b.first - a.first);
}

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

  // The yaw plot as last published.
  std::mutex mutex;
  visualization_msgs::MarkerArray last_plot;
  ros::NodeHandle nh;
  ros::Subscriber plot_sub = nh.subscribe<visualization_msgs::MarkerArray>(
      "/visual_gyro/yaw_plot", 100, [&](const visualization_msgs::MarkerArrayConstPtr& m) {
        std::lock_guard<std::mutex> l(mutex);
        last_plot = *m;
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
  EXPECT_EQ(summary.accuracy.frames, 50);
  EXPECT_EQ(summary.accuracy.with_truth, 50);
  EXPECT_LE(summary.accuracy.yaw_rmse_deg, 0.4);
  EXPECT_EQ(summary.imu_published, (summary.accuracy.frames - summary.accuracy.invalid));
  EXPECT_GE((summary.accuracy.frames - summary.accuracy.invalid), 45);
  // The car turns right by about 98 degrees: the rate is positive about the camera's y axis.
  double yaw_sum = 0.0;
  for (const auto& m : report.rotations) yaw_sum += m.yaw;
  EXPECT_NEAR(yaw_sum * 180.0 / M_PI, 97.9, 5.0);
  // Default stamps: the midpoint of the two images (the mean rate's time), on ~imu and ~rotation.
  for (const auto& m : report.rotations) {
    EXPECT_NEAR(m.header.stamp.toSec(), m.previous_stamp.toSec() + 0.5 * m.dt, 1e-6);
  }
  ASSERT_FALSE(report.imus.empty());
  const double first_image = bag.frames[0].info->header.stamp.toSec();
  EXPECT_NEAR(report.imus.front().header.stamp.toSec(), first_image + 0.05, 1e-6);

  ros::WallDuration(0.3).sleep();
  std::lock_guard<std::mutex> l(mutex);
  const visualization_msgs::Marker* estimate = findMarker(last_plot, "yaw_estimate");
  const visualization_msgs::Marker* truth = findMarker(last_plot, "yaw_ground_truth");
  ASSERT_TRUE(estimate && estimate->points.size() >= 2) << "no yaw plot of the estimate";
  ASSERT_TRUE(truth && truth->points.size() >= 2) << "no yaw plot of the ground truth (ground_truth topic)";
  EXPECT_EQ(estimate->type, visualization_msgs::Marker::LINE_STRIP);
  EXPECT_EQ(estimate->points.size(), 51u);
  EXPECT_TRUE(findMarker(last_plot, "rate_estimate") && findMarker(last_plot, "rate_ground_truth"));
  // Read off the plot through its labels: both lines end near the 97.9 degree turn.
  const double axis_x = estimate->points.front().x;
  const double estimate_end = readYawOffPlot(last_plot, axis_x, estimate->points.back().y);
  const double truth_end = readYawOffPlot(last_plot, axis_x, truth->points.back().y);
  EXPECT_NEAR(truth_end, 97.9, 2.0);
  EXPECT_NEAR(estimate_end, truth_end, 3.0);
  std::filesystem::remove_all(dir);
}

TEST(VisualGyroReplay, KittiTurnJpegCompressed) {
  std::string why;
  const std::string folder = visual_gyro::test::sharedSequence("kitti_turn", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  const std::string dir = visual_gyro::test::makeTempDir("replay_jpeg");
  const visual_gyro::Sequence sequence = visual_gyro::loadSequence(folder);
  bt::BagWriteOptions write_options;
  write_options.compression = visual_gyro::compressed_input::Compression::kJpeg;
  const std::string bag_path = dir + "/kitti_turn_jpeg.bag";
  ASSERT_EQ(bt::writeSequenceBag(sequence, bag_path, write_options).images, 51);
  const bt::BagContents bag = bt::readSequenceBag(bag_path);
  ASSERT_EQ(bag.frames.size(), 51u);
  ASSERT_TRUE(bag.frames[0].compressed) << "make_bag --compressed jpeg wrote raw images";
  EXPECT_FALSE(bag.frames[0].image);
  EXPECT_NE(bag.frames[0].compressed->format.find("jpeg"), std::string::npos);
  // About 10x smaller than the 1241 x 376 raw image.
  EXPECT_LT(bag.frames[0].compressed->data.size(), 1241u * 376u / 3);

  // The second nodelet (ns /compressed, ~image_transport compressed) decodes them.
  const visual_gyro::frame_player::PlayerOptions options = visual_gyro::ros_test::playerUnderNamespace("/compressed");
  const auto report = visual_gyro::frame_player::playFrames(bag, options);
  ASSERT_TRUE(report.ok) << report.error;
  const bt::OutputSummary summary =
      bt::evaluateOutputs(report.rotations, static_cast<int>(report.imus.size()), bag, "kitti_turn_jpeg90");
  std::printf("JPEG quality 90:\n%s\n%s\n", summary.text().c_str(), summary.json().c_str());
  EXPECT_EQ(summary.accuracy.frames, 50);
  EXPECT_GE((summary.accuracy.frames - summary.accuracy.invalid), 45);
  EXPECT_LE(summary.accuracy.yaw_rmse_deg, 0.4) << "the paper method's accuracy bound holds on JPEG input too";
  std::filesystem::remove_all(dir);
}

}  // namespace

int main(int argc, char** argv) {
  return visual_gyro::ros_test::runRosTests(argc, argv, "test_replay_ros", 1, [] { return RUN_ALL_TESTS(); });
}
