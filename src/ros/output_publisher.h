// What the visual_gyro nodelet publishes for a processed frame: the RotationEstimate, the Imu (with
// the policy for invalid estimates), the integrated orientation (PoseStamped and tf) and the yaw
// plot, optionally rotated into ~output_frame through tf2.
#pragma once

#include <memory>
#include <mutex>
#include <string>

#include <Eigen/Core>
#include <geometry_msgs/PoseStamped.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <std_msgs/Header.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include "node_diagnostics.h"
#include "node_parameters.h"
#include "visual_gyro/RotationEstimate.h"
#include "visual_gyro/visual_gyro.h"
#include "yaw_plot.h"

namespace visual_gyro {

/// The live (dynamic_reconfigure) settings the outputs depend on, as of one frame.
struct OutputSettings {
  std::string method;             ///< the estimator method, as published
  bool stamp_at_midpoint = true;  ///< estimates stamped between the two images
  bool publish_invalid = false;   ///< publish an Imu for an invalid estimate too
  double invalid_variance = 1.0;  ///< [(rad/s)^2] its rate variance (the rate is zero)
};

/// One processed frame, as the outputs need it.
struct FrameOutput {
  std_msgs::Header image_header;  ///< the image's stamp and camera frame
  bool had_previous = false;      ///< the frame was paired with a previous one: an estimate exists
  double previous_stamp = 0.0;    ///< that previous image's stamp [s]
  const FrameResult* result = nullptr;
  bool valid = false;             ///< paired and result->hasEstimate(): the estimate can be trusted
  Backend backend = Backend::kCpu;  ///< the backend that estimated it
  ros::WallTime wall_start;       ///< when the image callback began (latency)
};

namespace output_messages {

/// The RotationEstimate's status text: "" when valid, else the status' name and its reason
/// ("too_few_matches: 5 (need 8)").
std::string statusText(const FrameResult& result, bool valid);

/// The RotationEstimate of `frame` (had_previous must be true), with rotation, rates and
/// covariances rotated into the output frame by `to_output` (output <- camera). An invalid
/// estimate carries the identity rotation and a zero rate, as the offline evaluation scores it.
visual_gyro::RotationEstimatePtr rotationEstimate(const FrameOutput& frame, const std_msgs::Header& header,
                                                  const Eigen::Matrix3d& to_output, const OutputSettings& settings);

/// The Imu of `frame` (had_previous must be true; REP 145: no orientation, no acceleration) with
/// `header`: when valid, its rate and rate covariance rotated into the output frame by `to_output`
/// (output <- camera), as in its RotationEstimate; when invalid, null unless
/// settings.publish_invalid, then a zero rate with invalid_variance on the diagonal, so that a
/// filter barely moves.
sensor_msgs::ImuPtr imu(const FrameOutput& frame, const std_msgs::Header& header, const Eigen::Matrix3d& to_output,
                        const OutputSettings& settings);

}  // namespace output_messages

/// Publishes ~imu, ~rotation, ~orientation (+ tf) and ~yaw_plot. publish(), reset() and
/// outputRotation() are called by one frame at a time (the nodelet's frame lock); the yaw plot
/// also takes ground truth from another callback, under the publisher's own plot lock.
class OutputPublisher {
 public:
  OutputPublisher(const NodeParameters& params, NodeDiagnostics* health);

  /// Advertises the outputs in `pnh`; `connect_cb` runs when their subscribers change.
  void advertise(ros::NodeHandle& nh, ros::NodeHandle& pnh, const ros::SubscriberStatusCallback& connect_cb);
  /// An output is wanted: ~publish_tf is on, or a topic has a subscriber.
  bool wanted() const;

  /// Publishes what `frame` gives (its estimate, when paired, and the integrated orientation), its
  /// stamps moved by ~time_offset. False when the rotation into ~output_frame is not available yet,
  /// or a moved stamp would not be a positive time: nothing is published.
  bool publish(const FrameOutput& frame, const OutputSettings& settings);
  /// Forgets the integrated orientation and the yaw plot.
  void reset();
  /// A ground-truth pose for the yaw plot.
  void groundTruth(const geometry_msgs::PoseStamped& pose);

 private:
  /// Rotation output <- camera optical frame (identity without ~output_frame); false when the
  /// transform is not available yet.
  bool outputRotation(const std::string& camera_frame, Eigen::Matrix3d* rotation);
  /// Publishes the plot (when it has a subscriber) as of `stamp`; plot_mutex_ held.
  void publishYawPlotLocked(double stamp);

  const NodeParameters params_;
  NodeDiagnostics* health_;
  ros::Publisher imu_pub_, rotation_pub_, orientation_pub_, yaw_plot_pub_;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;

  Eigen::Matrix3d integrated_ = Eigen::Matrix3d::Identity();  ///< camera frame, since reset
  // The output frame's rotation, looked up once a second.
  std::string cached_tf_key_;
  Eigen::Matrix3d cached_output_rotation_ = Eigen::Matrix3d::Identity();
  ros::WallTime cached_tf_time_;
  bool have_cached_tf_ = false;

  std::mutex plot_mutex_;  ///< guards yaw_plot_
  YawPlot yaw_plot_;
};

}  // namespace visual_gyro
