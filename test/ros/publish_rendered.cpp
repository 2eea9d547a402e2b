// Test helper: a rendered camera. Publishes image + camera_info (image_transport, mono8) at ~rate Hz
// with wall-clock stamps, looping over one period of a smooth yaw oscillation (so the loop has no
// jump), for hztest.
#include <cmath>
#include <vector>

#include <Eigen/Geometry>
#include <image_transport/image_transport.h>
#include <ros/ros.h>
#include <sensor_msgs/image_encodings.h>

#include "ros_test_support.h"
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

  namespace vgt = visual_gyro::ros_test;
  const visual_gyro::RenderSettings settings = vgt::handheldScene();
  std::vector<sensor_msgs::Image> images;
  for (int k = 0; k < period; ++k) {
    const double yaw_deg = amplitude_deg * std::sin(2.0 * M_PI * k / period);
    const cv::Mat gray = visual_gyro::renderView(settings, vgt::yawRight(yaw_deg), Eigen::Vector3d::Zero());
    images.push_back(vgt::imageMsg(gray, sensor_msgs::image_encodings::MONO8, 0.0, frame_id));
  }
  sensor_msgs::CameraInfo info = vgt::cameraInfo(settings, frame_id);

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
