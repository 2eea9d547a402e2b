// The visual gyroscope as a ROS nodelet: camera images in, angular velocity (sensor_msgs/Imu),
// frame-to-frame rotation (visual_gyro/RotationEstimate), integrated orientation and a yaw plot out.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <geometry_msgs/PoseStamped.h>
#include <image_transport/image_transport.h>
#include <message_filters/subscriber.h>
#include <message_filters/time_synchronizer.h>
#include <nodelet/nodelet.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>

#include "input_probe.h"
#include "node_diagnostics.h"
#include "node_parameters.h"
#include "output_publisher.h"
#include "visual_gyro/VisualGyroConfig.h"
#include "visual_gyro/visual_gyro.h"

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
///
/// Parts: NodeParameters (node-only parameters, read once), reconfigure_settings (the live
/// settings -> pipeline settings), OutputPublisher (messages, Imu policy, integration, tf, yaw
/// plot), NodeDiagnostics (counts and the /diagnostics status), InputProbe (which input is
/// missing). This class keeps the subscriptions, the frame checks (stamps, camera) and the
/// pipeline.
///
/// Threads and locks. Image, camera_info, ground-truth and connect callbacks run on the nodelet's
/// single-threaded queue; the diagnostics timer and the dynamic_reconfigure server run on a
/// service queue that a thread of the nodelet spins, so neither waits for a frame (not on the
/// nodelet's multi-threaded queue: a manager may destroy the nodelet after that queue is gone).
/// Locks, always taken in this order (a later one may be taken while holding an earlier one,
/// never the reverse):
///   1. connect_mutex_: the subscriptions (connect callbacks come from other threads).
///   2. frame_mutex_: one frame's processing: the pipeline, the previous stamp, the camera, and
///      the OutputPublisher's integration and output-frame cache.
///   3. config_mutex_: the accepted live settings (copied out by a frame at its start, swapped by
///      the reconfigure callback; held for a copy only). The reconfigure server holds its own
///      mutex around the callback, before this one.
///   4. OutputPublisher's plot lock: the yaw plot (frames and the ground-truth callback).
///   5. NodeDiagnostics' lock: counts and problems (held inside each of its calls only).
class VisualGyroNodelet : public nodelet::Nodelet {
 public:
  VisualGyroNodelet();
  ~VisualGyroNodelet() override;

 private:
  using Config = visual_gyro::VisualGyroConfig;

  void onInit() override;
  /// Subscribes or unsubscribes the inputs as outputs gain or lose subscribers.
  void connectCb();
  /// Ends every input subscription (images, camera_info, ground truth); under connect_mutex_, or
  /// in the destructor.
  void shutdownInputs();
  void cameraCb(const sensor_msgs::ImageConstPtr& image, const sensor_msgs::CameraInfoConstPtr& info);
  void imageCb(const sensor_msgs::ImageConstPtr& image);
  /// `<image>/compressed` decoded here (~image_transport compressed without image_transport's plugin).
  void compressedCameraCb(const sensor_msgs::CompressedImageConstPtr& image,
                          const sensor_msgs::CameraInfoConstPtr& info);
  void compressedImageCb(const sensor_msgs::CompressedImageConstPtr& image);
  /// Decodes a compressed image; null (frame counted as skipped) when it cannot be decoded.
  sensor_msgs::ImageConstPtr decodeCompressed(const sensor_msgs::CompressedImage& image);
  void groundTruthCb(const geometry_msgs::PoseStampedConstPtr& pose);
  /// Accepts a live change through the gate (reconfigure_settings::refuseInvalid): each refused
  /// value is put back to the one in force in `config` (the server then publishes and stores it),
  /// with one error naming the settings and why, and a WARN on /diagnostics until a later change
  /// is accepted.
  void reconfigureCb(Config& config, uint32_t level);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);

  /// One image with the camera model it was taken with; `wall_start` is when the callback began.
  /// Takes frame_mutex_.
  void processImage(const sensor_msgs::Image& image, const CameraModel& camera, ros::WallTime wall_start);
  /// Makes the pipeline ready for `camera` (built on the first image, re-targeted when the camera
  /// changes) with `settings` (version `config_version`); false (frame skipped) when the camera is
  /// unusable.
  bool preparePipeline(const CameraModel& camera, const VisualGyroSettings& settings, uint64_t config_version);
  /// Keeps the diagnostics' calibration verdict (a WARN while the pipeline says the calibration
  /// does not fit the images) up to date with `result`.
  void reportCalibrationFit(const FrameResult& result);
  /// Forgets the previous frame, the integrated orientation and the yaw plot; `cause` is counted.
  void resetState(const std::string& cause);
  /// Skips a frame whose camera model is unusable (`why`): a throttled error, kept for the
  /// diagnostics, and counted under `reason`.
  void skipForCamera(const std::string& why, const std::string& reason);

  NodeParameters params_;   ///< read once in onInit, then constant
  NodeDiagnostics health_;  ///< thread-safe
  std::unique_ptr<OutputPublisher> outputs_;

  // --- ROS handles ---
  std::unique_ptr<image_transport::ImageTransport> it_;
  image_transport::CameraSubscriber camera_sub_;
  image_transport::Subscriber image_sub_;
  /// Counts what arrives while no pair does; updated (1 Hz, on subscription) under connect_mutex_.
  std::unique_ptr<InputProbe> probe_;
  ros::Subscriber ground_truth_sub_;
  bool decode_compressed_ = false;  ///< compressed requested, image_transport's plugin missing
  message_filters::Subscriber<sensor_msgs::CompressedImage> compressed_camera_sub_;
  message_filters::Subscriber<sensor_msgs::CameraInfo> compressed_info_sub_;
  std::unique_ptr<message_filters::TimeSynchronizer<sensor_msgs::CompressedImage, sensor_msgs::CameraInfo>>
      compressed_sync_;
  ros::Subscriber compressed_image_sub_;
  /// The diagnostics timer's and the reconfigure server's queue, spun by service_thread_ while
  /// service_running_; declared before them, so it outlives them.
  ros::CallbackQueue service_queue_;
  std::thread service_thread_;
  std::atomic<bool> service_running_{false};
  std::unique_ptr<dynamic_reconfigure::Server<Config>> reconfigure_server_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diagnostic_timer_;

  std::mutex connect_mutex_;             ///< 1: the subscriptions
  std::atomic<bool> subscribed_{false};  ///< also read by the diagnostics
  std::atomic<bool> reset_pending_{false};  ///< reset before the next frame (inputs re-subscribed)

  std::mutex frame_mutex_;  ///< 2: guards the pipeline state below
  std::unique_ptr<VisualGyro> pipeline_;
  uint64_t applied_config_version_ = 0;  ///< the live settings the pipeline runs with
  CameraModel camera_;
  bool have_camera_ = false;
  CameraModel failed_camera_;  ///< the last camera that could not be used (not retried)
  bool have_failed_camera_ = false;
  bool have_previous_ = false;  ///< the pipeline holds a previous frame
  double previous_stamp_ = 0.0;
  std::string backend_warning_;  ///< the backend factory's warning ("" when none)

  std::mutex config_mutex_;  ///< 3: guards the accepted live settings below
  Config config_;
  VisualGyroSettings settings_;  ///< the pipeline settings of config_ (through the settings table)
  bool have_config_ = false;
  uint64_t config_version_ = 0;  ///< counts accepted changes
};

}  // namespace visual_gyro
