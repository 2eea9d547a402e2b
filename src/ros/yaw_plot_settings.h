// The yaw plot's settings, apart from the plot (no ROS): the node's settings table (node_settings.h)
// reads and writes them.
#pragma once

#include <string>

namespace visual_gyro {

/// Geometry and content of the yaw plot.
struct YawPlotSettings {
  std::string frame_id = "visual_gyro_world";  ///< frame of every marker
  double window = 20.0;        ///< [s] time span shown; older points scroll out to the left
  double left = 2.0;           ///< [m] x of the time axis' start (the orientation axes sit at the origin)
  double width = 8.0;          ///< [m] length of the time axis (rviz x)
  double height = 3.0;         ///< [m] height of each panel (rviz y)
  double text_size = 0.22;     ///< [m] height of the labels
  double truth_tolerance = 0.005;  ///< [s] a ground-truth pose this close to the first image is its reference
  int max_points = 3000;       ///< points kept per series (also bounded by the window)
};

}  // namespace visual_gyro
