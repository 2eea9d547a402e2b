// Deterministic replay of a sequence bag through a running visual_gyro node: frames are published
// one at a time, each after the node has finished the previous one, so no frame is dropped
// whatever the machine's speed.
#pragma once

#include <string>
#include <vector>

#include <ros/ros.h>
#include <sensor_msgs/Imu.h>

#include "bag_tools.h"
#include "visual_gyro/RotationEstimate.h"

namespace visual_gyro {
namespace frame_player {

/// Options of playFrames.
struct PlayerOptions {
  bag_tools::BagTopics topics;          ///< topics to publish on (those of the bag by default)
  std::string output_ns = "/visual_gyro";  ///< the node's private namespace (its ~orientation etc.)
  double frame_timeout = 10.0;          ///< [s] wait for one frame's output
  double subscribe_timeout = 30.0;      ///< [s] wait for the node to subscribe to the images
  /// Topics that must have a subscriber other than this process (e.g. a rosbag recorder) before the
  /// first frame is sent.
  std::vector<std::string> wait_for_subscribers;
  bool collect = true;                  ///< keep the ~rotation and ~imu messages in the report
  bool verbose = false;                 ///< print one line per frame
};

/// What happened.
struct PlayerReport {
  bool ok = false;
  std::string error;                   ///< why not ok
  int published = 0;                   ///< frames sent
  int processed = 0;                   ///< frames the node answered (one ~orientation each)
  int timed_out = 0;                   ///< frames without an answer within frame_timeout
  std::vector<visual_gyro::RotationEstimate> rotations;  ///< when collect
  std::vector<sensor_msgs::Imu> imus;                    ///< when collect
  double wall_seconds = 0.0;
};

/// Publishes the bag's frames (image + camera_info through image_transport, preceded by the ground
/// truth poses and gyro samples up to the frame's stamp, and /tf_static once) and waits after each
/// frame for the node's ~orientation message, which it publishes once per processed frame.
/// Subscribing to the outputs is also what makes the lazy node subscribe to the images. Uses its own
/// callback queue, so the caller may run a spinner.
PlayerReport playFrames(const bag_tools::BagContents& bag, const PlayerOptions& options);

}  // namespace frame_player
}  // namespace visual_gyro
