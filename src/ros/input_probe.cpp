#include "input_probe.h"

#include <image_transport/camera_common.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>

namespace visual_gyro {

InputProbe::InputProbe(const ros::NodeHandle& nh, const ros::NodeHandle& pnh, image_transport::ImageTransport* it,
                       bool decode_compressed)
    : nh_(nh), pnh_(pnh), it_(it), decode_compressed_(decode_compressed) {}

void InputProbe::update(bool wanted, bool force_start) {
  const bool paired = paired_.exchange(0) > 0;
  wanted = wanted && (force_start || !paired);
  if (!wanted) {
    stop();
    return;
  }
  if (running_) return;
  const std::string image_topic = nh_.resolveName("image");
  if (decode_compressed_) {
    // The same topic the camera subscription reads: image_transport's plugin is missing, so the
    // probe cannot go through image_transport either.
    const boost::function<void(const sensor_msgs::CompressedImageConstPtr&)> on_compressed =
        [this](const sensor_msgs::CompressedImageConstPtr&) { ++images_; };
    compressed_sub_ = nh_.subscribe<sensor_msgs::CompressedImage>(image_topic + "/compressed", 1, on_compressed);
  } else {
    const boost::function<void(const sensor_msgs::ImageConstPtr&)> on_image =
        [this](const sensor_msgs::ImageConstPtr&) { ++images_; };
    image_transport::TransportHints hints("raw", ros::TransportHints(), pnh_);
    image_sub_ = it_->subscribe("image", 1, on_image, ros::VoidPtr(), hints);
  }
  const boost::function<void(const sensor_msgs::CameraInfoConstPtr&)> on_info =
      [this](const sensor_msgs::CameraInfoConstPtr&) { ++infos_; };
  info_sub_ = nh_.subscribe<sensor_msgs::CameraInfo>(image_transport::getCameraInfoTopic(image_topic), 1, on_info);
  running_ = true;
}

void InputProbe::stop() {
  if (!running_) return;
  image_sub_.shutdown();
  compressed_sub_.shutdown();
  info_sub_.shutdown();
  running_ = false;
}

}  // namespace visual_gyro
