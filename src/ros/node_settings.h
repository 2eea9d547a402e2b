// The visual_gyro nodelet's own settings (input, frames, tf, yaw plot, intrinsics without
// camera_info, and the live node behaviour: gaps, stamps, invalid estimates) as a settings table of
// the same kind as the pipeline's (setting_field.h), and the one gate every setting value passes,
// whichever table holds it. No ROS: the settings files generator and the unit tests use it too.
#pragma once

#include <string>
#include <vector>

#include "visual_gyro/setting_field.h"
#include "yaw_plot_settings.h"

namespace visual_gyro {

/// The node's own settings; defaults here, ranges, units, docs and tiers in nodeSettingFields().
/// The live ones (max_gap, stamp_at_midpoint, publish_invalid, invalid_variance) change through
/// dynamic_reconfigure, whose configuration holds the values in force; the others are read once
/// at start.
struct NodeSettings {
  bool use_camera_info = true;       ///< intrinsics from camera_info (else fx, fy, cx, cy, D)
  std::string image_transport = "raw";  ///< transport of the image subscription
  int queue_size = 1;                ///< images waiting while one is processed
  std::string output_frame;          ///< "": the camera's optical frame; else outputs rotated into it
  std::string world_frame = "visual_gyro_world";  ///< frame of ~orientation and ~yaw_plot
  bool publish_tf = false;           ///< broadcast world_frame -> tf_child_frame
  std::string tf_child_frame = "visual_gyro_camera";
  YawPlotSettings plot;              ///< plot_window, plot_width, plot_height, plot_points, ground_truth_tolerance
  /// [px] Intrinsics when use_camera_info is false; fx 0: not set; fy -1: fx; cx, cy -1: the
  /// image centre.
  double fx = 0.0, fy = -1.0, cx = -1.0, cy = -1.0;
  std::string distortion_model = "none";
  std::vector<double> D;             ///< distortion coefficients in the model's order
  int mono16_bit_depth = 0;          ///< mono16 scaling: 0 = per frame, else the camera's bit depth
  double max_gap = 1.0;              ///< [s] a larger gap between image stamps resets the state
  bool stamp_at_midpoint = true;     ///< outputs stamped between the two images (else the current one)
  bool publish_invalid = false;      ///< an Imu for invalid estimates too
  double invalid_variance = 1.0;     ///< [(rad/s)^2] its angular-velocity variance (> 0)
  /// [s] Added to every output stamp (~imu, ~rotation, ~orientation, tf) to put it on the IMU's
  /// clock, t_imu = t_camera + time_offset (what calibrate_imu measures); the yaw plot stays on the
  /// camera's clock.
  double time_offset = 0.0;
};

/// Every node setting, each defined once with its range, unit, doc, tier and whether it is live.
/// No name is also a pipeline setting (visualGyroSettingFields()).
const std::vector<SettingField<NodeSettings>>& nodeSettingFields();

/// The node setting called `name`, or nullptr.
const SettingField<NodeSettings>* findNodeSetting(const std::string& name);

/// Sets one node setting from text: "" when `value` parses and is accepted, else why, naming the
/// setting (and *settings is unchanged).
std::string applyNodeSetting(NodeSettings* settings, const std::string& name, const std::string& value);

/// "" when every node setting in `settings` is accepted, else the first refusal, naming it.
std::string validateNodeSettings(const NodeSettings& settings);

/// One setting of either table, without its struct: what the gate, the generated files and the
/// tests need.
struct AnySetting {
  const SettingSpec* spec = nullptr;
  std::string default_text;  ///< the default value as text (SettingField::text)
  bool node = false;         ///< a node setting (else the pipeline's)
};

/// Every setting of both tables: the node's, then the pipeline's (each in its table's order).
std::vector<AnySetting> everySetting();

/// The setting called `name` in either table; spec nullptr when none.
AnySetting findAnySetting(const std::string& name);

/// The gate: "" when `value` is an accepted value of the setting `name` (of either table: parsed
/// and checked by applySetting or applyNodeSetting), else why, naming the setting. There are no
/// rules across settings, so each value is checked alone.
std::string checkSettingValue(const std::string& name, const std::string& value);

}  // namespace visual_gyro
