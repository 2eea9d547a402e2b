// The visual_gyro nodelet's input probe: while it is subscribed to image + camera_info but no
// synchronized pair arrives, a plain subscription to each counts what does arrive, so the
// diagnostics can say which one is missing.
#pragma once

#include <atomic>
#include <cstdint>
#include <utility>

#include <image_transport/image_transport.h>
#include <ros/ros.h>

namespace visual_gyro {

class InputProbe {
 public:
  /// `decode_compressed`: the images are read from `<image>/compressed` without image_transport.
  InputProbe(const ros::NodeHandle& nh, const ros::NodeHandle& pnh, image_transport::ImageTransport* it,
             bool decode_compressed);

  /// A synchronized pair reached the node (any thread).
  void pairArrived() { ++paired_; }
  /// Runs the probe while `wanted` and either `force_start` or no pair came since the last call;
  /// stops it otherwise. One caller at a time (the nodelet's connect lock). Probe callbacks only
  /// touch atomics, so stopping cannot wait for a frame being processed.
  void update(bool wanted, bool force_start);
  /// Images and camera_info messages counted since the last call (any thread).
  std::pair<uint64_t, uint64_t> take() { return {images_.exchange(0), infos_.exchange(0)}; }

 private:
  void stop();

  ros::NodeHandle nh_, pnh_;
  image_transport::ImageTransport* it_;
  bool decode_compressed_;
  image_transport::Subscriber image_sub_;
  ros::Subscriber compressed_sub_, info_sub_;
  bool running_ = false;
  std::atomic<uint64_t> images_{0}, infos_{0}, paired_{0};
};

}  // namespace visual_gyro
