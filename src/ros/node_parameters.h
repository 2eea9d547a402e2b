// The visual_gyro nodelet's node-only private parameters, read once at start: input, output
// frames, tf, the yaw plot and the intrinsics used when there is no camera_info. The pipeline's
// settings (method, thresholds, plausibility) are live dynamic_reconfigure settings instead.
#pragma once

#include <string>
#include <vector>

#include <ros/node_handle.h>

#include "visual_gyro/camera_model.h"
#include "yaw_plot.h"

namespace visual_gyro {

/// Largest |~time_offset| accepted [s]: camera-IMU offsets are tens of milliseconds.
constexpr double kMaxTimeOffset = 1.0;

struct NodeParameters {
  bool use_camera_info = true;
  std::string transport = "raw";  ///< ~image_transport
  int queue_size = 1;             ///< ~queue_size: images waiting while one is processed (>= 1)
  std::string backend = "auto";   ///< ~backend request
  std::string output_frame;       ///< "" = the camera's optical frame
  std::string world_frame = "visual_gyro_world";
  bool publish_tf = false;
  std::string tf_child_frame = "visual_gyro_camera";
  YawPlotSettings plot;           ///< ~plot_*, ~ground_truth_tolerance (frame: world_frame)
  // Intrinsics when use_camera_info is false (fy, cx, cy < 0: fx and the image centre).
  double fx = 0.0, fy = -1.0, cx = -1.0, cy = -1.0;
  std::string distortion_model = "none";
  std::vector<double> distortion;  ///< ~D
  int mono16_bit_depth = 0;        ///< mono16 scaling: 0 = per frame, else the camera's bit depth
  /// ~time_offset [s], in [-kMaxTimeOffset, kMaxTimeOffset]: added to every output stamp (~imu,
  /// ~rotation, ~orientation, tf) to put it on the IMU's clock, t_imu = t_camera + time_offset
  /// (what calibrate_imu measures). The yaw plot stays on the camera's clock.
  double time_offset = 0.0;
  /// Why a parameter is unusable ("" when all are): the node then publishes nothing.
  std::string problem;

  /// Reads the parameters from the private node handle (defaults as above).
  static NodeParameters read(const ros::NodeHandle& pnh);

  /// The camera model from ~fx ... for an image of this size; false (and `why`) when unusable.
  bool cameraFor(int width, int height, CameraModel* camera, std::string* why) const;
};

}  // namespace visual_gyro
