// Test helper: a rendered camera. Publishes image + camera_info (image_transport, mono8) at ~rate Hz
// with wall-clock stamps, looping over one period of a smooth yaw oscillation (so the loop has no
// jump), for hztest.
#include <cmath>
#include <vector>

#include <Eigen/Geometry>
#include <image_transport/image_transport.h>
#include <ros/ros.h>
#include <sensor_msgs/image_encodings.h>

#include "ros_conversions.h"
#include "visual_gyro/camera_model.h"
#include "visual_gyro/renderer.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "publish_rendered");
  ros::NodeHandle nh, pnh("~");
  double rate = 10.0, amplitude_deg = 5.0;
  int period = 40;
  std::string frame_id;
  pnh.param("rate", rate, rate);
  pnh.param("amplitude_deg", amplitude_deg, amplitude_deg);
  pnh.param("period_frames", period, period);
  pnh.param<std::string>("frame_id", frame_id, "test_camera_optical");

  visual_gyro::RenderSettings settings;
  settings.preset = visual_gyro::RenderPreset::kHandheld;
  settings.setCentredCamera(320, 240, 250.0);
  settings.noise_sigma = 1.0;
  std::vector<sensor_msgs::Image> images;
  for (int k = 0; k < period; ++k) {
    const double yaw = amplitude_deg * M_PI / 180.0 * std::sin(2.0 * M_PI * k / period);
    const cv::Mat gray = visual_gyro::renderView(
        settings, Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()).toRotationMatrix(), Eigen::Vector3d::Zero());
    sensor_msgs::Image m;
    m.header.frame_id = frame_id;
    m.width = static_cast<uint32_t>(gray.cols);
    m.height = static_cast<uint32_t>(gray.rows);
    m.encoding = sensor_msgs::image_encodings::MONO8;
    m.step = m.width;
    m.data.resize(static_cast<size_t>(m.step) * m.height);
    for (int r = 0; r < gray.rows; ++r) std::copy(gray.ptr<uint8_t>(r), gray.ptr<uint8_t>(r) + gray.cols, &m.data[r * m.step]);
    images.push_back(m);
  }
  sensor_msgs::CameraInfo info = visual_gyro::ros_conversions::cameraInfoFromModel(visual_gyro::CameraModel(
      settings.fx, settings.fy, settings.cx, settings.cy, settings.width, settings.height));
  info.header.frame_id = frame_id;

  image_transport::ImageTransport it(nh);
  image_transport::CameraPublisher pub = it.advertiseCamera("image", 1);
  ROS_INFO("publish_rendered: %zu frames of %dx%d at %.1f Hz on %s", images.size(), settings.width, settings.height,
           rate, pub.getTopic().c_str());
  ros::Rate loop(rate);
  for (size_t k = 0; ros::ok(); ++k) {
    sensor_msgs::Image& image = images[k % images.size()];
    image.header.stamp = ros::Time::now();
    image.header.seq = static_cast<uint32_t>(k);
    info.header.stamp = image.header.stamp;
    pub.publish(image, info);
    ros::spinOnce();
    loop.sleep();
  }
  return 0;
}
