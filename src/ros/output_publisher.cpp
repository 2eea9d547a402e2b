#include "output_publisher.h"

#include <algorithm>

#include <geometry_msgs/TransformStamped.h>
#include <visualization_msgs/MarkerArray.h>

#include "ros_conversions.h"

namespace visual_gyro {

namespace conv = ros_conversions;

namespace output_messages {

namespace {

uint32_t count(int n) { return static_cast<uint32_t>(std::max(n, 0)); }

/// The frame's angular velocity [rad/s] in the output frame (output <- camera `to_output`). An
/// invalid estimate has a zero rate: what a consumer that ignores `valid` integrates, and what
/// the offline evaluation scores.
Eigen::Vector3d outputRate(const FrameOutput& frame, const Eigen::Matrix3d& to_output) {
  const Eigen::Vector3d omega = frame.valid ? frame.result->angular_velocity : Eigen::Vector3d::Zero();
  return to_output * omega;
}

/// The covariance [(rad/s)^2] of the frame's angular velocity in the output frame.
Eigen::Matrix3d outputRateCovariance(const FrameOutput& frame, const Eigen::Matrix3d& to_output) {
  return to_output * frame.result->angular_velocity_covariance * to_output.transpose();
}

}  // namespace

std::string statusText(const FrameResult& result, bool valid) {
  if (valid) return "";
  const std::string name = frameStatusName(result.status);
  return result.reason.empty() ? name : name + ": " + result.reason;
}

visual_gyro::RotationEstimatePtr rotationEstimate(const FrameOutput& frame, const std_msgs::Header& header,
                                                  const Eigen::Matrix3d& to_output, const OutputSettings& settings) {
  const FrameResult& result = *frame.result;
  const RotationResult& rot = result.rotation;
  const double stamp = frame.image_header.stamp.toSec();
  // An invalid estimate is the identity (with a zero rate, outputRate): what a consumer that
  // ignores `valid` integrates, and what the offline evaluation scores.
  const Eigen::Matrix3d rotation = frame.valid ? rot.rotation : Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d rotation_out = to_output * rotation * to_output.transpose();
  const Eigen::Vector3d omega_out = outputRate(frame, to_output);

  visual_gyro::RotationEstimatePtr msg(new visual_gyro::RotationEstimate);
  msg->header = header;
  msg->previous_stamp.fromSec(frame.previous_stamp);
  msg->dt = stamp - frame.previous_stamp;
  msg->rotation = conv::toMsg(Eigen::Quaterniond(rotation_out));
  if (frame.valid) {
    msg->yaw = rot.yaw;
    msg->pitch = rot.pitch;
    msg->roll = rot.roll;
  }
  msg->angular_velocity.x = omega_out.x();
  msg->angular_velocity.y = omega_out.y();
  msg->angular_velocity.z = omega_out.z();
  conv::toRowMajor(to_output * rot.covariance * to_output.transpose(), &msg->rotation_covariance);
  conv::toRowMajor(outputRateCovariance(frame, to_output), &msg->angular_velocity_covariance);
  msg->features = count(result.features);
  msg->matches = count(rot.matches_used);
  msg->tracked = count(result.tracked);
  msg->half_resolution = result.half_resolution;
  msg->hypotheses = count(rot.hypotheses_drawn);
  msg->hypotheses_accepted = count(rot.hypotheses_accepted);
  msg->winning_votes = count(rot.winning_votes);
  msg->inliers = count(rot.inliers);
  msg->method = settings.method;
  msg->backend = backendName(frame.backend);
  msg->detect_ms = result.times.detect;
  msg->describe_ms = result.times.describe;
  msg->match_ms = result.times.match;
  msg->align_ms = result.times.align;
  msg->estimate_ms = result.times.estimate;
  msg->total_ms = result.times.total;
  msg->valid = frame.valid;
  msg->status = statusText(result, frame.valid);
  return msg;
}

sensor_msgs::ImuPtr imu(const FrameOutput& frame, const std_msgs::Header& header, const Eigen::Matrix3d& to_output,
                        const OutputSettings& settings) {
  if (!frame.valid && !settings.publish_invalid) return nullptr;
  sensor_msgs::ImuPtr imu(new sensor_msgs::Imu);
  imu->header = header;
  imu->orientation.w = 1.0;
  imu->orientation_covariance[0] = -1.0;          // REP 145: no orientation
  imu->linear_acceleration_covariance[0] = -1.0;  // REP 145: no acceleration
  if (frame.valid) {
    const Eigen::Vector3d omega = outputRate(frame, to_output);
    imu->angular_velocity.x = omega.x();
    imu->angular_velocity.y = omega.y();
    imu->angular_velocity.z = omega.z();
    conv::toRowMajor(outputRateCovariance(frame, to_output), &imu->angular_velocity_covariance);
  } else {
    conv::toRowMajor(Eigen::Matrix3d::Identity() * settings.invalid_variance, &imu->angular_velocity_covariance);
  }
  return imu;
}

}  // namespace output_messages

OutputPublisher::OutputPublisher(const NodeParameters& params, NodeDiagnostics* health)
    : params_(params), health_(health), yaw_plot_(params.plot) {}

void OutputPublisher::advertise(ros::NodeHandle& nh, ros::NodeHandle& pnh,
                                const ros::SubscriberStatusCallback& connect_cb) {
  tf_buffer_.reset(new tf2_ros::Buffer());
  tf_listener_.reset(new tf2_ros::TransformListener(*tf_buffer_, nh));
  if (params_.publish_tf) tf_broadcaster_.reset(new tf2_ros::TransformBroadcaster());
  imu_pub_ = pnh.advertise<sensor_msgs::Imu>("imu", 10, connect_cb, connect_cb);
  rotation_pub_ = pnh.advertise<visual_gyro::RotationEstimate>("rotation", 10, connect_cb, connect_cb);
  orientation_pub_ = pnh.advertise<geometry_msgs::PoseStamped>("orientation", 10, connect_cb, connect_cb);
  yaw_plot_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("yaw_plot", 10, connect_cb, connect_cb);
}

bool OutputPublisher::wanted() const {
  return params_.publish_tf || imu_pub_.getNumSubscribers() > 0 || rotation_pub_.getNumSubscribers() > 0 ||
         orientation_pub_.getNumSubscribers() > 0 || yaw_plot_pub_.getNumSubscribers() > 0;
}

void OutputPublisher::reset() {
  integrated_.setIdentity();
  std::lock_guard<std::mutex> lock(plot_mutex_);
  yaw_plot_.reset();
}

bool OutputPublisher::publish(const FrameOutput& frame, const OutputSettings& settings) {
  const std_msgs::Header& image_header = frame.image_header;
  const double stamp = image_header.stamp.toSec();
  Eigen::Matrix3d to_output = Eigen::Matrix3d::Identity();
  const bool have_output_frame = outputRotation(image_header.frame_id, &to_output);
  if (frame.had_previous && frame.valid) integrated_ = integrated_ * frame.result->rotation.rotation;
  if (!have_output_frame) return false;  // outputRotation warned
  // On the IMU's clock; a zero shift leaves every stamp exactly as computed.
  const ros::Duration shift(params_.time_offset);
  const double first_stamp = frame.had_previous ? frame.previous_stamp : stamp;
  if (!(first_stamp + params_.time_offset > 0.0)) {
    ROS_ERROR_THROTTLE(10.0, "visual_gyro: image stamp %.6f s + ~time_offset %.6f s is not a positive time; outputs "
                       "held back", stamp, params_.time_offset);
    return false;
  }

  if (frame.had_previous) {
    std_msgs::Header header = image_header;
    if (!params_.output_frame.empty()) header.frame_id = params_.output_frame;
    if (settings.stamp_at_midpoint) header.stamp.fromSec(0.5 * (frame.previous_stamp + stamp));
    header.stamp += shift;
    visual_gyro::RotationEstimatePtr msg = output_messages::rotationEstimate(frame, header, to_output, settings);
    msg->previous_stamp += shift;
    const sensor_msgs::ImuPtr imu = output_messages::imu(frame, header, to_output, settings);
    msg->latency_ms = (ros::WallTime::now() - frame.wall_start).toSec() * 1e3;
    if (imu) {
      imu_pub_.publish(imu);
      health_->imuPublished();
    }
    rotation_pub_.publish(msg);
    const RotationResult& rot = frame.result->rotation;
    const double vote_ratio =
        rot.hypotheses_accepted > 0 ? static_cast<double>(rot.winning_votes) / rot.hypotheses_accepted : 0.0;
    health_->estimatePublished(frame.valid, msg->status, msg->latency_ms, rot.matches_used, vote_ratio,
                               frame.result->half_resolution);
  }

  // Integrated orientation: the first frame after a reset is the identity. It is the camera's
  // orientation when this image was taken, so it carries the image's stamp (not the midpoint).
  geometry_msgs::PoseStampedPtr pose(new geometry_msgs::PoseStamped);
  pose->header.stamp = image_header.stamp + shift;
  pose->header.frame_id = params_.world_frame;
  pose->pose.orientation = conv::toMsg(Eigen::Quaterniond(to_output * integrated_ * to_output.transpose()));
  orientation_pub_.publish(pose);
  if (tf_broadcaster_) {
    geometry_msgs::TransformStamped t;
    t.header = pose->header;
    t.child_frame_id = params_.tf_child_frame;
    t.transform.rotation = pose->pose.orientation;
    tf_broadcaster_->sendTransform(t);
  }
  std::lock_guard<std::mutex> lock(plot_mutex_);
  yaw_plot_.addEstimate(stamp, integrated_);
  publishYawPlotLocked(stamp);
  return true;
}

bool OutputPublisher::outputRotation(const std::string& camera_frame, Eigen::Matrix3d* rotation) {
  const std::string& output_frame = params_.output_frame;
  if (output_frame.empty() || output_frame == camera_frame) {
    rotation->setIdentity();
    return true;
  }
  const std::string key = output_frame + "<-" + camera_frame;
  const ros::WallTime now = ros::WallTime::now();
  // Camera mounts are static: look the transform up once, then re-check once a second so a
  // corrected calibration is picked up.
  if (have_cached_tf_ && key == cached_tf_key_ && (now - cached_tf_time_).toSec() < 1.0) {
    *rotation = cached_output_rotation_;
    return true;
  }
  try {
    const geometry_msgs::TransformStamped t = tf_buffer_->lookupTransform(output_frame, camera_frame, ros::Time(0));
    const Eigen::Matrix3d r = conv::fromMsg(t.transform.rotation).toRotationMatrix();
    if (!have_cached_tf_ || key != cached_tf_key_ || !r.isApprox(cached_output_rotation_, 1e-9)) {
      ROS_INFO_THROTTLE(10.0, "visual_gyro: rotation %s -> %s is now [%.4f %.4f %.4f %.4f] (x y z w)",
                        camera_frame.c_str(), output_frame.c_str(), t.transform.rotation.x,
                        t.transform.rotation.y, t.transform.rotation.z, t.transform.rotation.w);
      // A different output rotation makes the integrated orientation discontinuous: restart it.
      if (have_cached_tf_) reset();
    }
    cached_tf_key_ = key;
    cached_output_rotation_ = r;
    cached_tf_time_ = now;
    have_cached_tf_ = true;
    *rotation = r;
    return true;
  } catch (const tf2::TransformException& e) {
    if (have_cached_tf_ && key == cached_tf_key_) {
      *rotation = cached_output_rotation_;
      return true;
    }
    ROS_WARN_THROTTLE(10.0, "visual_gyro: no transform %s -> %s yet (%s); outputs held back", camera_frame.c_str(),
                      output_frame.c_str(), e.what());
    return false;
  }
}

void OutputPublisher::groundTruth(const geometry_msgs::PoseStamped& pose) {
  std::lock_guard<std::mutex> lock(plot_mutex_);
  const double stamp = pose.header.stamp.toSec();
  yaw_plot_.addTruth(stamp, conv::fromMsg(pose.pose.orientation));
  // Truth that arrives after its image would otherwise wait for the next image to be drawn.
  if (!yaw_plot_.empty()) publishYawPlotLocked(stamp);
}

void OutputPublisher::publishYawPlotLocked(double stamp) {
  if (yaw_plot_pub_.getNumSubscribers() == 0 || yaw_plot_.empty()) return;
  visualization_msgs::MarkerArrayPtr markers(new visualization_msgs::MarkerArray(yaw_plot_.markers(stamp)));
  yaw_plot_pub_.publish(markers);
}

}  // namespace visual_gyro
