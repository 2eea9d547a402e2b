// launch/replay.launch with the real `rosbag play` on a bag of ../shared/data/kitti_turn, against
// the frame-by-frame replay (play_frames' code) through a second nodelet of the same configuration
// (rosbag_replay.test): at least 95 % of the frame pairs give an estimate, and the yaw RMSE stays
// within 10 % of the frame-by-frame replay's. The bag plays at rate 1 whenever this build processes
// a frame in at most half the frame period (every optimised build); a build that cannot (under
// sanitizers a frame takes most of the 100 ms period) plays slower, so that the node drops no
// frames and the comparison stays like for like: a live node rightly drops the frames it cannot
// keep up with, and a pair that spans two frame periods is a different measurement. Skipped with
// a message when the data is absent.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

#include <ros/ros.h>
#include <sensor_msgs/Imu.h>

#include "bag_tools.h"
#include "frame_player.h"
#include "ros_test_support.h"
#include "test_support.h"
#include "visual_gyro/RotationEstimate.h"
#include "visual_gyro/sequence.h"

namespace {

namespace bt = visual_gyro::bag_tools;

/// Starts `argv` in its own process group with stdout and stderr to `log`; returns its pid.
pid_t spawn(const std::vector<std::string>& argv, const std::string& log) {
  // Everything the child needs is prepared before fork (only async-signal-safe calls after it).
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const pid_t pid = fork();
  if (pid != 0) return pid;
  setpgid(0, 0);
  const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0) _exit(126);
  dup2(fd, 1);
  dup2(fd, 2);
  execvp(args[0], args.data());
  _exit(127);
}

/// SIGINT to the process group (roslaunch stops its nodes), SIGKILL after `grace` seconds.
void stopGroup(pid_t pid, double grace) {
  kill(-pid, SIGINT);
  for (int i = 0; i < static_cast<int>(grace * 10); ++i) {
    if (waitpid(pid, nullptr, WNOHANG) == pid) return;
    usleep(100000);
  }
  kill(-pid, SIGKILL);
  waitpid(pid, nullptr, 0);
}

std::string tail(const std::string& path, size_t chars) {
  int status = 0;
  const std::string text = visual_gyro::test::runCommand("cat '" + path + "'", &status);
  return text.size() > chars ? text.substr(text.size() - chars) : text;
}

TEST(RosbagReplay, KittiTurnThroughRosbagPlayMatchesFrameByFrame) {
  std::string why;
  const std::string folder = visual_gyro::test::sharedSequence("kitti_turn", &why);
  if (folder.empty()) GTEST_SKIP() << why;

  const std::string dir = visual_gyro::test::makeTempDir("rosbag_replay");
  const std::string bag_path = dir + "/kitti_turn.bag";
  const bt::BagWriteSummary written =
      bt::writeSequenceBag(visual_gyro::loadSequence(folder), bag_path, bt::BagWriteOptions());
  ASSERT_EQ(written.images, 51);
  const bt::BagContents bag = bt::readSequenceBag(bag_path);
  const int pairs = written.images - 1;

  // The reference: every frame, one at a time, through the frame-by-frame nodelet.
  const visual_gyro::frame_player::PlayerOptions options = visual_gyro::ros_test::playerUnderNamespace("/frame_by_frame");
  const auto reference = visual_gyro::frame_player::playFrames(bag, options);
  ASSERT_TRUE(reference.ok) << reference.error;
  const bt::OutputSummary frame_by_frame =
      bt::evaluateOutputs(reference.rotations, static_cast<int>(reference.imus.size()), bag, "kitti_turn");
  std::printf("frame by frame (%.1f s):\n%s\n", reference.wall_seconds, frame_by_frame.text().c_str());
  ASSERT_EQ(frame_by_frame.accuracy.frames, pairs);

  // Rate 1 when a frame takes at most half the frame period, else as much slower as needed.
  const double frame_period = (written.last_stamp - written.first_stamp) / pairs;
  const double per_frame_s = 1e-3 * frame_by_frame.latency_ms;
  ASSERT_TRUE(std::isfinite(per_frame_s) && per_frame_s > 0.0) << "no latency in the frame-by-frame summary";
  const double rate = std::min(1.0, std::floor(100.0 * 0.5 * frame_period / per_frame_s) / 100.0);
  ASSERT_GT(rate, 0.0) << "a frame takes " << per_frame_s << " s: too slow to replay";
  std::printf("frame period %.3f s, %.3f s per frame through the node: rosbag play at rate %.2f\n", frame_period,
              per_frame_s, rate);
  char rate_text[16];
  std::snprintf(rate_text, sizeof(rate_text), "%.2f", rate);

  // The same bag through replay.launch and rosbag play. The player starts paused and is
  // released by replay_control.py once the node has subscribed (our ~rotation subscription is what
  // makes the lazy node subscribe), and kept alive so that the last frames are still processed.
  std::mutex mutex;
  std::vector<visual_gyro::RotationEstimate> rotations;
  int imus = 0;
  ros::NodeHandle nh;
  ros::Subscriber rotation_sub = nh.subscribe<visual_gyro::RotationEstimate>(
      "/camera/visual_gyro/rotation", 100, [&](const visual_gyro::RotationEstimateConstPtr& m) {
        std::lock_guard<std::mutex> l(mutex);
        rotations.push_back(*m);
      });
  ros::Subscriber imu_sub = nh.subscribe<sensor_msgs::Imu>("/camera/visual_gyro/imu", 100,
                                                           [&](const sensor_msgs::ImuConstPtr&) {
                                                             std::lock_guard<std::mutex> l(mutex);
                                                             ++imus;
                                                           });
  const std::string launch_log = dir + "/roslaunch.log";
  const pid_t launch = spawn({"roslaunch", "visual_gyro", "replay.launch", "bag:=" + bag_path, std::string("rate:=") + rate_text,
                              "player_args:=--pause --keep-alive"},
                             launch_log);
  ASSERT_GT(launch, 0);
  char last_stamp[32];
  std::snprintf(last_stamp, sizeof(last_stamp), "%.6f", written.last_stamp);
  int status = 0;
  const std::string control = visual_gyro::test::runCommand(
      std::string("/usr/bin/python3 ") + VISUAL_GYRO_SOURCE_DIR + "/scripts/replay_control.py --last-stamp " +
          last_stamp + " --subscribed /camera/camera_info --settle 1.5 --timeout 200",
      &status);
  stopGroup(launch, 15.0);
  ASSERT_EQ(status, 0) << control << "\nroslaunch log:\n" << tail(launch_log, 3000);

  std::lock_guard<std::mutex> l(mutex);
  const bt::OutputSummary played = bt::evaluateOutputs(rotations, imus, bag, "kitti_turn");
  std::printf("rosbag play at rate %s:\n%s\n%s\n", rate_text, played.text().c_str(), played.json().c_str());
  EXPECT_GE(played.accuracy.frames, static_cast<int>(std::ceil(0.95 * pairs))) << "estimates for fewer than 95 % of the frames";
  EXPECT_GE((played.accuracy.frames - played.accuracy.invalid), static_cast<int>(std::ceil(0.95 * (frame_by_frame.accuracy.frames - frame_by_frame.accuracy.invalid))));
  EXPECT_LE(played.accuracy.yaw_rmse_deg, 1.10 * frame_by_frame.accuracy.yaw_rmse_deg)
      << "frame by frame: " << frame_by_frame.accuracy.yaw_rmse_deg << " deg";
  EXPECT_EQ(played.accuracy.with_truth, played.accuracy.frames);
  std::filesystem::remove_all(dir);
}

}  // namespace

int main(int argc, char** argv) {
  return visual_gyro::ros_test::runRosTests(argc, argv, "test_rosbag_replay", 1, [] { return RUN_ALL_TESTS(); });
}
