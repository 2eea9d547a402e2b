// play_frames: replays a sequence bag through a running visual_gyro node one frame at a time,
// waiting for the node's answer to each frame, so no frame is dropped however slow the machine.
// (`rosbag play` in launch/replay.launch plays in real time instead.)
#include <cstdio>
#include <string>
#include <vector>

#include <ros/ros.h>

#include "bag_tools.h"
#include "frame_player.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "play_frames", ros::init_options::AnonymousName);
  std::vector<std::string> args;
  ros::removeROSArgs(argc, argv, args);
  if (args.size() < 2) {
    std::fprintf(stderr,
                 "usage: play_frames <sequence.bag> [--ns /visual_gyro] [--timeout S] [--wait-for TOPIC]... [--verbose]\n"
                 "  --ns          the visual_gyro node's private namespace (default /visual_gyro)\n"
                 "  --timeout     seconds to wait for the answer to one frame (default 10)\n"
                 "  --wait-for    do not start before TOPIC has another subscriber (e.g. a recorder)\n");
    return 2;
  }
  visual_gyro::frame_player::PlayerOptions options;
  options.collect = false;
  for (size_t i = 2; i < args.size(); ++i) {
    const std::string& a = args[i];
    const bool has_value = i + 1 < args.size();
    if (a == "--ns" && has_value) options.output_ns = args[++i];
    else if (a == "--timeout" && has_value) options.frame_timeout = std::stod(args[++i]);
    else if (a == "--wait-for" && has_value) options.wait_for_subscribers.push_back(args[++i]);
    else if (a == "--verbose") options.verbose = true;
    else {
      std::fprintf(stderr, "play_frames: unknown or incomplete option '%s'\n", a.c_str());
      return 2;
    }
  }
  try {
    const auto bag = visual_gyro::bag_tools::readSequenceBag(args[1], options.topics);
    ROS_INFO("play_frames: %zu frames, %zu poses, %zu gyro samples from %s", bag.frames.size(), bag.poses.size(),
             bag.gyro.size(), args[1].c_str());
    const auto report = visual_gyro::frame_player::playFrames(bag, options);
    std::printf("play_frames: published %d frames, %d answered, %d timed out, %.2f s wall\n", report.published,
                report.processed, report.timed_out, report.wall_seconds);
    if (!report.ok) {
      std::fprintf(stderr, "play_frames: %s\n", report.error.c_str());
      return 1;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "play_frames: %s\n", e.what());
    return 1;
  }
  return 0;
}
