// The visual gyroscope as a ROS nodelet: camera images in, angular velocity (sensor_msgs/Imu),
// frame-to-frame rotation (visual_gyro/RotationEstimate), integrated orientation and a yaw plot out.
#pragma once

#include <atomic>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <geometry_msgs/PoseStamped.h>
#include <image_transport/image_transport.h>
#include <message_filters/subscriber.h>
#include <message_filters/time_synchronizer.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include "node_diagnostics.h"
#include "visual_gyro/VisualGyroConfig.h"
#include "visual_gyro/visual_gyro.h"
#include "yaw_plot.h"

namespace visual_gyro {

/// Nodelet `visual_gyro/VisualGyroNodelet`.
///
/// Subscribes (lazily: only while an output has a subscriber, or ~publish_tf is on) to `image`
/// (+ its `camera_info`, unless ~use_camera_info is false) through image_transport, queue
/// ~queue_size (1), or, for ~image_transport compressed without image_transport's plugin, to
/// `<image>/compressed` decoded here; and to `ground_truth` (geometry_msgs/PoseStamped, optional,
/// for the yaw plot). Publishes ~imu, ~rotation (stamped at the midpoint of the two images unless
/// ~stamp_at_midpoint is false), ~orientation (at the image's stamp), ~yaw_plot (MarkerArray) and
/// /diagnostics. Rotation convention: the frame-to-frame
/// rotation R maps current-frame bearings into the previous frame (b_prev = R b_cur), in the
/// camera's optical frame (x right, y down, z forward) or, when ~output_frame is set, rotated into
/// that frame with the tf2 transform (R_out = T R T^T, w_out = T w). Units: rad, rad/s, s.
class VisualGyroNodelet : public nodelet::Nodelet {
 public:
  VisualGyroNodelet();
  ~VisualGyroNodelet() override;

 private:
  using Config = visual_gyro::VisualGyroConfig;

  void onInit() override;
  /// Subscribes or unsubscribes the inputs as outputs gain or lose subscribers.
  void connectCb();
  void cameraCb(const sensor_msgs::ImageConstPtr& image, const sensor_msgs::CameraInfoConstPtr& info);
  void imageCb(const sensor_msgs::ImageConstPtr& image);
  /// `<image>/compressed` decoded here (~image_transport compressed without image_transport's plugin).
  void compressedCameraCb(const sensor_msgs::CompressedImageConstPtr& image,
                          const sensor_msgs::CameraInfoConstPtr& info);
  void compressedImageCb(const sensor_msgs::CompressedImageConstPtr& image);
  /// Decodes a compressed image; null (frame counted as skipped) when it cannot be decoded.
  sensor_msgs::ImageConstPtr decodeCompressed(const sensor_msgs::CompressedImage& image);
  void groundTruthCb(const geometry_msgs::PoseStampedConstPtr& pose);
  void reconfigureCb(Config& config, uint32_t level);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);
  /// Starts or stops the probe: while subscribed to image + camera_info but no synchronized pair
  /// arrives, a plain subscription to each counts what does arrive, so the diagnostics can say
  /// which one is missing. Called by the diagnostics timer (1 Hz) and on subscription.
  void updateProbe(bool force_start);
  /// updateProbe() with connect_mutex_ held.
  void updateProbeLocked(bool force_start);

  /// One image with the camera model it was taken with; `wall_start` is when the callback began.
  void processImage(const sensor_msgs::Image& image, const CameraModel& camera, ros::WallTime wall_start);
  /// Camera model from the ~fx... parameters for an image of this size.
  bool cameraFromParameters(int width, int height, CameraModel* camera, std::string* why) const;
  /// Forgets the previous frame, the integrated orientation and the yaw plot; `cause` is counted.
  void resetState(const std::string& cause);
  /// Counts a skipped frame under `reason`.
  void skip(const std::string& reason);
  /// Skips a frame whose camera model is unusable (`why`): a throttled error, kept for the
  /// diagnostics, and counted under `reason`.
  void skipForCamera(const std::string& why, const std::string& reason);
  /// Rotation from the camera optical frame into ~output_frame (identity when unset). False when
  /// the transform is not available yet.
  bool outputRotation(const std::string& camera_frame, Eigen::Matrix3d* rotation);
  /// Publishes the yaw plot (when it has a subscriber) as of `stamp` [s].
  void publishYawPlot(double stamp);
  /// Pipeline settings from a dynamic_reconfigure config (every cfg entry the settings table
  /// knows, plus ~backend): "" or the first setting that does not parse or is out of range.
  std::string settingsFromConfig(const Config& config, VisualGyroSettings* settings) const;

  // --- ROS handles ---
  std::unique_ptr<image_transport::ImageTransport> it_;
  image_transport::CameraSubscriber camera_sub_;
  image_transport::Subscriber image_sub_;
  image_transport::Subscriber probe_image_sub_;  ///< see updateProbe()
  ros::Subscriber probe_compressed_sub_;         ///< the probe's image input when decoding ourselves
  ros::Subscriber probe_info_sub_;
  bool probing_ = false;                         ///< guarded by connect_mutex_
  std::atomic<uint64_t> probe_images_{0}, probe_infos_{0};  ///< since the last diagnostics update
  std::atomic<uint64_t> paired_images_{0};  ///< synchronized callbacks since the last probe check
  ros::Subscriber ground_truth_sub_;
  // Compressed input decoded by the nodelet itself.
  message_filters::Subscriber<sensor_msgs::CompressedImage> compressed_camera_sub_;
  message_filters::Subscriber<sensor_msgs::CameraInfo> compressed_info_sub_;
  std::unique_ptr<message_filters::TimeSynchronizer<sensor_msgs::CompressedImage, sensor_msgs::CameraInfo>>
      compressed_sync_;
  ros::Subscriber compressed_image_sub_;
  ros::Publisher imu_pub_, rotation_pub_, orientation_pub_, yaw_plot_pub_;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  std::unique_ptr<dynamic_reconfigure::Server<Config>> reconfigure_server_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diagnostic_timer_;

  std::mutex connect_mutex_;  ///< guards the subscriptions (connect callbacks run on other threads)
  std::atomic<bool> subscribed_{false};  // also read by the diagnostics
  std::mutex state_mutex_;    ///< guards everything below

  // --- parameters ---
  bool use_camera_info_ = true;
  std::string transport_ = "raw";   ///< ~image_transport
  bool decode_compressed_ = false;  ///< compressed requested, image_transport's plugin missing
  int queue_size_ = 1;              ///< ~queue_size: images waiting while one is processed
  // Intrinsics when use_camera_info_ is false (fy, cx, cy < 0: fx and the image centre).
  double param_fx_ = 0.0, param_fy_ = -1.0, param_cx_ = -1.0, param_cy_ = -1.0;
  std::string param_distortion_model_ = "none";
  std::vector<double> param_distortion_;
  std::string backend_request_ = "auto";
  std::string output_frame_;
  std::string world_frame_ = "visual_gyro_world";
  bool publish_tf_ = false;
  std::string tf_child_frame_ = "visual_gyro_camera";
  int mono16_bit_depth_ = 0;  ///< mono16 scaling: 0 = per frame, else the camera's bit depth
  Config config_;
  bool have_config_ = false;

  // --- pipeline state ---
  std::unique_ptr<VisualGyro> pipeline_;
  CameraModel camera_;
  bool have_camera_ = false;
  CameraModel failed_camera_;       ///< the last camera that could not be used (not retried)
  bool have_failed_camera_ = false;
  bool have_previous_ = false;      ///< the pipeline holds a previous frame
  double previous_stamp_ = 0.0;
  bool reset_pending_ = false;      ///< reset before the next frame (inputs were re-subscribed)
  Eigen::Matrix3d integrated_ = Eigen::Matrix3d::Identity();  ///< camera frame, since reset
  std::string backend_used_;
  std::string last_warning_;
  std::string parameter_problem_;  ///< a private parameter read at start is unusable

  // --- output frame ---
  std::string cached_tf_key_;
  Eigen::Matrix3d cached_output_rotation_ = Eigen::Matrix3d::Identity();
  ros::WallTime cached_tf_time_;
  bool have_cached_tf_ = false;

  // --- yaw plot ---
  YawPlot yaw_plot_;

  // --- health (counts, causes; /diagnostics) ---
  NodeDiagnostics health_;
};

}  // namespace visual_gyro
