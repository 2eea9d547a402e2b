// play_frames: replays a sequence bag through a running visual_gyro node one frame at a time,
// waiting for the node's answer to each frame, so no frame is dropped however slow the machine.
// (`rosbag play` in launch/replay.launch plays in real time instead.)
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include <ros/ros.h>

#include "bag_tools.h"
#include "command_line.h"
#include "frame_player.h"

namespace {

const char* const kUsage =
    "usage: play_frames <sequence.bag> [--ns /visual_gyro] [--timeout S] [--wait-for TOPIC]... [--verbose]\n"
    "  --ns          the visual_gyro node's private namespace (default /visual_gyro)\n"
    "  --timeout     seconds to wait for the answer to one frame (default 10)\n"
    "  --wait-for    do not start before TOPIC has another subscriber (e.g. a recorder)\n";

int run(std::vector<std::string> words) {
  std::vector<char*> argv;
  for (std::string& w : words) argv.push_back(&w[0]);
  std::string bag_path;
  visual_gyro::frame_player::PlayerOptions options;
  options.collect = false;
  for (visual_gyro::cli::Arguments args(static_cast<int>(argv.size()), argv.data()); args.next();) {
    if (args.is("-h") || args.is("--help")) {
      std::printf("%s", kUsage);
      return 0;
    } else if (args.is("--ns")) {
      options.output_ns = args.value();
    } else if (args.is("--timeout")) {
      options.frame_timeout = args.doubleValue(1e-3, 1e6);
    } else if (args.is("--wait-for")) {
      options.wait_for_subscribers.push_back(args.value());
    } else if (args.is("--verbose")) {
      options.verbose = true;
    } else if (args.isOption() || !bag_path.empty()) {
      args.unexpected();
    } else {
      bag_path = args.current();
    }
  }
  if (bag_path.empty()) throw visual_gyro::cli::UsageError("no sequence bag given");
  const auto bag = visual_gyro::bag_tools::readSequenceBag(bag_path, options.topics);
  ROS_INFO("play_frames: %zu frames, %zu poses, %zu gyro samples from %s", bag.frames.size(), bag.poses.size(),
           bag.gyro.size(), bag_path.c_str());
  const auto report = visual_gyro::frame_player::playFrames(bag, options);
  std::printf("play_frames: published %d frames, %d answered, %d timed out, %.2f s wall\n", report.published,
              report.processed, report.timed_out, report.wall_seconds);
  if (!report.ok) throw std::runtime_error(report.error);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "play_frames", ros::init_options::AnonymousName);
  std::vector<std::string> words;
  ros::removeROSArgs(argc, argv, words);  // words[0] is the program
  const int status = visual_gyro::cli::runCommand("play_frames", kUsage, [&] { return run(words); });
  ros::shutdown();  // roscpp's threads stop before static destruction frees what they read
  return status;
}
