// The visual_gyro nodelet's start-up parameters: every setting of both tables (node_settings.h)
// read from the private parameters through the one gate, and the node's own settings kept for
// the run. The pipeline's and the node's live settings then reach the node through
// dynamic_reconfigure (reconfigure_settings.h), which reads the values left on the parameter
// server here.
#pragma once

#include <string>

#include <ros/node_handle.h>

#include "node_settings.h"
#include "visual_gyro/camera_model.h"

namespace visual_gyro {

/// The node's own settings as read at start, with the ~backend request. The live ones among them
/// (max_gap, ...) are only their start-up values: the dynamic_reconfigure configuration holds
/// those in force.
struct NodeParameters : NodeSettings {
  std::string backend;  ///< ~backend request: the pipeline setting `backend`, read once at start
  /// The start-up parameters refused, each naming the setting and why, joined with "; " ("" when
  /// none): each was replaced by its default.
  std::string refused;

  /// Reads every setting of both tables present among the private parameters of `pnh`. A value the
  /// gate refuses (checkSettingValue: not of its type, out of range, NaN, infinite) is logged as an
  /// error naming it, listed in `refused`, and replaced by its default, also on the parameter
  /// server, so that dynamic_reconfigure starts from values in force; an accepted one is written
  /// back with its setting's type (a yaml `1` for a double reads as 1.0).
  static NodeParameters read(const ros::NodeHandle& pnh);

  /// The camera model from ~fx ... for an image of this size; false (and `why`) when unusable.
  bool cameraFor(int width, int height, CameraModel* camera, std::string* why) const;
};

}  // namespace visual_gyro
