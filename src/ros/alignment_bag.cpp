#include "alignment_bag.h"

#include <stdexcept>

#include <image_transport/camera_common.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <tf2_msgs/TFMessage.h>

#include "bag_tools.h"
#include "compressed_input.h"
#include "ros_conversions.h"

namespace visual_gyro {
namespace alignment_bag {
namespace {

void openBag(const std::string& path, rosbag::Bag* bag) {
  try {
    bag->open(path, rosbag::bagmode::Read);
  } catch (const rosbag::BagException& e) {
    throw std::runtime_error("cannot read bag '" + path + "': " + e.what());
  }
}

}  // namespace

Topics withDefaults(const Topics& topics) {
  const bag_tools::BagTopics made;  // make_bag's topics
  Topics t = topics;
  if (t.image.empty()) t.image = made.image;
  if (t.imu.empty()) t.imu = made.gyro;
  if (t.camera_info.empty()) t.camera_info = image_transport::getCameraInfoTopic(t.image);
  return t;
}

Scan scanBag(const std::string& bag_path, const Topics& given) {
  const Topics topics = withDefaults(given);
  rosbag::Bag bag;
  openBag(bag_path, &bag);
  Scan scan;
  int infos = 0;
  const std::string compressed = topics.image + "/compressed";
  std::vector<geometry_msgs::TransformStamped> statics;
  rosbag::View view(bag, rosbag::TopicQuery({topics.image, compressed, topics.camera_info, topics.imu, "/tf_static"}));
  for (const rosbag::MessageInstance& m : view) {
    if (m.getTopic() == "/tf_static") {
      if (auto tf = m.instantiate<tf2_msgs::TFMessage>())
        statics.insert(statics.end(), tf->transforms.begin(), tf->transforms.end());
    } else if (m.getTopic() == topics.imu) {
      if (auto imu = m.instantiate<sensor_msgs::Imu>()) {
        if (scan.imu.empty()) scan.imu_frame = imu->header.frame_id;
        GyroSample s;
        s.stamp = imu->header.stamp.toSec();
        s.angular_velocity = Eigen::Vector3d(imu->angular_velocity.x, imu->angular_velocity.y, imu->angular_velocity.z);
        scan.imu.push_back(s);
      }
    } else if (m.getTopic() == topics.camera_info) {
      if (auto info = m.instantiate<sensor_msgs::CameraInfo>()) {
        if (infos++ == 0) scan.camera_frame = info->header.frame_id;
      }
    } else if (auto image = m.instantiate<sensor_msgs::Image>()) {
      scan.image_stamps.push_back(image->header.stamp.toSec());
      if (scan.camera_frame.empty()) scan.camera_frame = image->header.frame_id;
    } else if (auto image = m.instantiate<sensor_msgs::CompressedImage>()) {
      scan.image_stamps.push_back(image->header.stamp.toSec());
      if (scan.camera_frame.empty()) scan.camera_frame = image->header.frame_id;
    }
  }
  bag.close();
  for (const geometry_msgs::TransformStamped& t : statics) {
    if (t.header.frame_id == scan.imu_frame && t.child_frame_id == scan.camera_frame) {
      scan.imu_from_camera = ros_conversions::fromMsg(t.transform.rotation).toRotationMatrix();
      scan.has_imu_from_camera = true;
    }
  }
  if (scan.image_stamps.empty())
    throw std::runtime_error("bag '" + bag_path + "' has no images on " + topics.image + " (or " + compressed + ")");
  if (infos == 0)
    throw std::runtime_error("bag '" + bag_path + "' has no camera_info on " + topics.camera_info +
                             " (give it with --camera-info-topic)");
  return scan;
}

int forEachImage(const std::string& bag_path, const Topics& given, const FrameCallback& callback,
                 std::string* first_problem) {
  const Topics topics = withDefaults(given);
  rosbag::Bag bag;
  openBag(bag_path, &bag);
  int skipped = 0;
  auto skip = [&](const std::string& why) {
    if (skipped++ == 0 && first_problem != nullptr) *first_problem = why;
  };
  bool have_camera = false;
  std::string camera_problem = "no camera_info in the bag";
  CameraModel camera;
  auto useInfo = [&](const sensor_msgs::CameraInfo& info) {
    std::string why;
    have_camera = ros_conversions::cameraModelFromInfo(info, &camera, &why);
    if (!have_camera) camera_problem = "camera_info unusable: " + why;
  };
  // Images recorded before the first camera_info take it too (a camera's calibration is fixed).
  rosbag::View infos(bag, rosbag::TopicQuery(topics.camera_info));
  for (const rosbag::MessageInstance& m : infos) {
    if (auto info = m.instantiate<sensor_msgs::CameraInfo>()) {
      useInfo(*info);
      break;
    }
  }
  rosbag::View view(bag, rosbag::TopicQuery({topics.image, topics.image + "/compressed", topics.camera_info}));
  for (const rosbag::MessageInstance& m : view) {
    if (m.getTopic() == topics.camera_info) {
      if (auto info = m.instantiate<sensor_msgs::CameraInfo>()) useInfo(*info);
      continue;
    }
    sensor_msgs::ImageConstPtr image = m.instantiate<sensor_msgs::Image>();
    cv::Mat gray;
    try {
      if (!image) {
        auto compressed = m.instantiate<sensor_msgs::CompressedImage>();
        if (!compressed) continue;
        image = compressed_input::decode(*compressed);
      }
      gray = ros_conversions::toGray(*image, 0);
    } catch (const std::invalid_argument& e) {
      skip(e.what());
      continue;
    }
    if (!have_camera) {
      skip(camera_problem);
      continue;
    }
    callback(gray, image->header.stamp.toSec(), camera);
  }
  bag.close();
  return skipped;
}

}  // namespace alignment_bag
}  // namespace visual_gyro
