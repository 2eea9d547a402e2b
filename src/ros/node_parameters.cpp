#include "node_parameters.h"

#include <algorithm>
#include <cmath>

namespace visual_gyro {

NodeParameters NodeParameters::read(const ros::NodeHandle& pnh) {
  NodeParameters p;
  pnh.param("use_camera_info", p.use_camera_info, p.use_camera_info);
  pnh.param("image_transport", p.transport, p.transport);
  pnh.param("queue_size", p.queue_size, p.queue_size);
  p.queue_size = std::max(p.queue_size, 1);
  pnh.param("backend", p.backend, p.backend);
  pnh.param("output_frame", p.output_frame, p.output_frame);
  pnh.param("world_frame", p.world_frame, p.world_frame);
  pnh.param("publish_tf", p.publish_tf, p.publish_tf);
  pnh.param("tf_child_frame", p.tf_child_frame, p.tf_child_frame);
  p.plot.frame_id = p.world_frame;
  pnh.param("plot_window", p.plot.window, p.plot.window);
  pnh.param("plot_width", p.plot.width, p.plot.width);
  pnh.param("plot_height", p.plot.height, p.plot.height);
  pnh.param("plot_points", p.plot.max_points, p.plot.max_points);
  pnh.param("ground_truth_tolerance", p.plot.truth_tolerance, p.plot.truth_tolerance);
  pnh.param("fx", p.fx, p.fx);
  pnh.param("fy", p.fy, p.fy);
  pnh.param("cx", p.cx, p.cx);
  pnh.param("cy", p.cy, p.cy);
  pnh.param("distortion_model", p.distortion_model, p.distortion_model);
  pnh.param("D", p.distortion, p.distortion);
  pnh.param("mono16_bit_depth", p.mono16_bit_depth, p.mono16_bit_depth);
  if (p.mono16_bit_depth != 0 && (p.mono16_bit_depth < 8 || p.mono16_bit_depth > 16))
    p.problem = "~mono16_bit_depth must be 0 (per frame) or 8..16, got " + std::to_string(p.mono16_bit_depth);
  pnh.param("time_offset", p.time_offset, p.time_offset);
  if (!(std::abs(p.time_offset) <= kMaxTimeOffset))
    p.problem = "~time_offset must lie in [-" + std::to_string(kMaxTimeOffset) + ", " + std::to_string(kMaxTimeOffset) +
                "] s, got " + std::to_string(p.time_offset);
  return p;
}

bool NodeParameters::cameraFor(int width, int height, CameraModel* camera, std::string* why) const {
  const double fx_used = fx;
  const double fy_used = fy > 0.0 ? fy : fx;
  const double cx_used = cx >= 0.0 ? cx : (width - 1) / 2.0;
  const double cy_used = cy >= 0.0 ? cy : (height - 1) / 2.0;
  DistortionModel model = DistortionModel::kNone;
  if (!parseDistortionModel(distortion_model, &model)) {
    *why = "~distortion_model '" + distortion_model + "' is not supported (none, plumb_bob, radtan, equidistant)";
    return false;
  }
  if (!(fx_used > 0.0)) {
    *why = "~use_camera_info is false but ~fx is not set (give ~fx, ~fy, ~cx, ~cy)";
    return false;
  }
  std::vector<double> d = distortion;
  if (std::all_of(d.begin(), d.end(), [](double v) { return v == 0.0; })) {
    d.clear();
    model = DistortionModel::kNone;
  }
  *camera = CameraModel(fx_used, fy_used, cx_used, cy_used, width, height, model, d);
  return true;
}

}  // namespace visual_gyro
