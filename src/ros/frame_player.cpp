#include "frame_player.h"

#include <algorithm>
#include <atomic>
#include <set>

#include <geometry_msgs/PoseStamped.h>
#include <image_transport/image_transport.h>
#include <ros/callback_queue.h>
#include <tf2_msgs/TFMessage.h>
#include <xmlrpcpp/XmlRpcValue.h>

namespace visual_gyro {
namespace frame_player {

namespace {

/// Subscribers of `topic` known to the master, this node excluded.
int otherSubscribers(const std::string& topic) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", args, result, payload, false)) return 0;
  if (payload.getType() != XmlRpc::XmlRpcValue::TypeArray || payload.size() < 2) return 0;
  XmlRpc::XmlRpcValue& subscribers = payload[1];
  int count = 0;
  for (int i = 0; i < subscribers.size(); ++i) {
    if (static_cast<std::string>(subscribers[i][0]) != topic) continue;
    for (int j = 0; j < subscribers[i][1].size(); ++j)
      if (static_cast<std::string>(subscribers[i][1][j]) != ros::this_node::getName()) ++count;
  }
  return count;
}

/// The player's publishers: the images (raw through image_transport, or compressed as recorded, on
/// <image>/compressed beside a camera_info) and the bag's poses, gyro samples and static transforms.
struct PlayerPublishers {
  bool compressed = false;
  image_transport::CameraPublisher camera;
  ros::Publisher compressed_image, info, pose, gyro, tf;

  int imageSubscribers() const { return compressed ? compressed_image.getNumSubscribers() : camera.getNumSubscribers(); }
  std::string imageTopic() const { return compressed ? compressed_image.getTopic() : camera.getTopic(); }
};

/// Advertises what the bag holds and publishes its static transforms once (latched).
void advertise(const bag_tools::BagContents& bag, const PlayerOptions& options, ros::NodeHandle* nh,
               image_transport::ImageTransport* it, PlayerPublishers* pub) {
  pub->compressed = !bag.frames.empty() && bag.frames.front().compressed;
  if (pub->compressed) {
    pub->compressed_image = nh->advertise<sensor_msgs::CompressedImage>(options.topics.image + "/compressed", 5);
    pub->info = nh->advertise<sensor_msgs::CameraInfo>(options.topics.camera_info, 5);
  } else {
    pub->camera = it->advertiseCamera(options.topics.image, 5);
  }
  if (!bag.poses.empty()) pub->pose = nh->advertise<geometry_msgs::PoseStamped>(options.topics.ground_truth, 100);
  if (!bag.gyro.empty()) pub->gyro = nh->advertise<sensor_msgs::Imu>(options.topics.gyro, 1000);
  if (!bag.static_transforms.empty()) {
    pub->tf = nh->advertise<tf2_msgs::TFMessage>("/tf_static", 1, true);
    tf2_msgs::TFMessage tf;
    tf.transforms = bag.static_transforms;
    pub->tf.publish(tf);
  }
}

/// Waits until the node subscribed to the images and every options.wait_for_subscribers topic has
/// another subscriber, then lets the connections settle; "" when so, else why not (timeout).
std::string waitForSubscribers(const PlayerPublishers& pub, const PlayerOptions& options, ros::CallbackQueue* queue) {
  // The lazy node subscribes to the images once it sees our output subscriptions.
  const ros::WallTime wait_start = ros::WallTime::now();
  auto waited = [&wait_start]() { return (ros::WallTime::now() - wait_start).toSec(); };
  while (ros::ok() && pub.imageSubscribers() == 0) {
    if (waited() > options.subscribe_timeout) {
      return "nobody subscribed to " + pub.imageTopic() + " within " + std::to_string(options.subscribe_timeout) +
             " s (is the visual_gyro node running, with its image input remapped there?)";
    }
    queue->callAvailable(ros::WallDuration(0.02));
  }
  for (const std::string& topic : options.wait_for_subscribers) {
    while (ros::ok() && otherSubscribers(ros::names::resolve(topic)) == 0) {
      if (waited() > options.subscribe_timeout) {
        return "nobody subscribed to " + topic + " within " + std::to_string(options.subscribe_timeout) + " s";
      }
      queue->callAvailable(ros::WallDuration(0.05));
    }
  }
  // Registered with the master is not yet connected: give the connections a moment.
  const ros::WallTime settle = ros::WallTime::now() + ros::WallDuration(0.5);
  while (ros::ok() && ros::WallTime::now() < settle) queue->callAvailable(ros::WallDuration(0.02));
  return "";
}

/// Publishes the frames one at a time (each preceded by the poses and gyro samples up to its
/// stamp), each time waiting up to frame_timeout for `answers` to grow; counts into `report`.
void publishFrames(const bag_tools::BagContents& bag, const PlayerOptions& options, const PlayerPublishers& pub,
                   const std::atomic<int>& answers, ros::CallbackQueue* queue, PlayerReport* report) {
  size_t pose_index = 0, gyro_index = 0;
  for (const bag_tools::BagFrame& frame : bag.frames) {
    if (!ros::ok()) break;
    const ros::Time stamp = frame.info->header.stamp;
    for (; pose_index < bag.poses.size() && bag.poses[pose_index]->header.stamp <= stamp; ++pose_index)
      pub.pose.publish(bag.poses[pose_index]);
    for (; gyro_index < bag.gyro.size() && bag.gyro[gyro_index]->header.stamp <= stamp; ++gyro_index)
      pub.gyro.publish(bag.gyro[gyro_index]);
    const int before = answers.load();
    if (frame.compressed) {
      pub.info.publish(frame.info);
      pub.compressed_image.publish(frame.compressed);
    } else if (frame.image) {
      pub.camera.publish(*frame.image, *frame.info);
    }
    ++report->published;
    const ros::WallTime sent = ros::WallTime::now();
    while (ros::ok() && answers.load() == before && (ros::WallTime::now() - sent).toSec() < options.frame_timeout)
      queue->callAvailable(ros::WallDuration(0.005));
    if (answers.load() == before) {
      ++report->timed_out;
      ROS_WARN("play_frames: no output for the frame at %.6f within %.1f s", stamp.toSec(), options.frame_timeout);
    } else {
      ++report->processed;
    }
    if (options.verbose) {
      ROS_INFO("play_frames: frame %d/%zu at %.6f: %s", report->published, bag.frames.size(), stamp.toSec(),
               answers.load() == before ? "no answer" : "done");
    }
  }
}

}  // namespace

PlayerReport playFrames(const bag_tools::BagContents& bag, const PlayerOptions& options) {
  PlayerReport report;
  const ros::WallTime start = ros::WallTime::now();
  ros::CallbackQueue queue;
  ros::NodeHandle nh;
  nh.setCallbackQueue(&queue);
  image_transport::ImageTransport it(nh);
  PlayerPublishers pub;
  advertise(bag, options, &nh, &it, &pub);

  std::atomic<int> answers{0};
  ros::Subscriber orientation_sub = nh.subscribe<geometry_msgs::PoseStamped>(
      options.output_ns + "/orientation", 100,
      [&answers](const geometry_msgs::PoseStampedConstPtr&) { ++answers; });
  ros::Subscriber rotation_sub, imu_sub;
  if (options.collect) {
    rotation_sub = nh.subscribe<visual_gyro::RotationEstimate>(
        options.output_ns + "/rotation", 100,
        [&report](const visual_gyro::RotationEstimateConstPtr& m) { report.rotations.push_back(*m); });
    imu_sub = nh.subscribe<sensor_msgs::Imu>(options.output_ns + "/imu", 100,
                                             [&report](const sensor_msgs::ImuConstPtr& m) { report.imus.push_back(*m); });
  }
  report.error = waitForSubscribers(pub, options, &queue);
  if (!report.error.empty()) return report;

  publishFrames(bag, options, pub, answers, &queue, &report);
  // Let the last ~rotation/~imu messages (published before ~orientation) arrive.
  const ros::WallTime drain = ros::WallTime::now() + ros::WallDuration(0.3);
  while (ros::ok() && ros::WallTime::now() < drain) queue.callAvailable(ros::WallDuration(0.02));
  report.ok = report.timed_out == 0 && report.published == static_cast<int>(bag.frames.size());
  if (!report.ok && report.error.empty()) {
    report.error = std::to_string(report.timed_out) + " of " + std::to_string(report.published) +
                   " frames got no answer";
  }
  report.wall_seconds = (ros::WallTime::now() - start).toSec();
  return report;
}

}  // namespace frame_player
}  // namespace visual_gyro
