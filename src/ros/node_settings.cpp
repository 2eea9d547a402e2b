#include "node_settings.h"

#include "visual_gyro/visual_gyro.h"

namespace visual_gyro {

namespace {

using Field = SettingField<NodeSettings>;

Field user(Field f) {
  f.tier = SettingTier::kUser;
  return f;
}

// Read once at start: the subscriptions, publishers and intrinsics are made from them.
Field atStart(Field f) {
  f.live = false;
  return f;
}

Field withSpecial(Field f, double special, std::string meaning) {
  f.has_special = true;
  f.special = special;
  f.special_doc = std::move(meaning);
  return f;
}

Field plotField(const SettingField<YawPlotSettings>& inner) { return atStart(nestedField(inner, &NodeSettings::plot)); }

std::vector<Field> makeFields() {
  using S = NodeSettings;
  using P = YawPlotSettings;
  std::vector<Field> f;
  f.push_back(user(atStart(boolField<S>(
      "use_camera_info", &S::use_camera_info,
      "intrinsics and distortion from camera_info; false: the plain image with `fx`, `fy`, `cx`, `cy`, "
      "`distortion_model` and `D`"))));
  f.push_back(user(atStart(stringField<S>(
      "image_transport", &S::image_transport, {},
      "transport of the image subscription: `raw`, or `compressed` (decoded by the node when image_transport's "
      "plugin is missing)"))));
  f.push_back(user(atStart(intField<S>(
      "queue_size", &S::queue_size, 1, 1000, "",
      "images queued while one is processed (1: the freshest image on a live camera; more for bag replay)"))));
  f.push_back(user(atStart(stringField<S>(
      "output_frame", &S::output_frame, {},
      "\"\": outputs in the camera's optical frame (the image's frame_id); else rotated into this frame (tf2)"))));
  f.push_back(user(atStart(boolField<S>(
      "publish_tf", &S::publish_tf,
      "broadcast `world_frame` -> `tf_child_frame` (the integrated orientation); also keeps the node subscribed"))));
  f.push_back(user(doubleField<S>("max_gap", &S::max_gap, 0.001, 3600.0, "s",
                                  "a larger gap between image stamps resets the state (one warning)")));
  f.push_back(user(boolField<S>("publish_invalid", &S::publish_invalid,
                                "also publish `~imu` for invalid estimates: zero rate, `invalid_variance`")));
  Field variance = user(doubleField<S>(
      "invalid_variance", &S::invalid_variance, 0.0, 1e6, "(rad/s)^2",
      "angular-velocity variance of such an Imu (a zero covariance would read as unknown)"));
  variance.min_exclusive = true;
  f.push_back(variance);
  // Camera-IMU clock offsets are tens of milliseconds; a second or more is a wrong unit or clock.
  f.push_back(user(atStart(doubleField<S>(
      "time_offset", &S::time_offset, -1.0, 1.0, "s",
      "added to every output stamp: t_imu = t_camera + time_offset (measured by `make calibrate`)"))));
  f.push_back(boolField<S>(
      "stamp_at_midpoint", &S::stamp_at_midpoint,
      "stamp `~imu` and `~rotation` at the midpoint of the two images (false: at the current image)"));
  f.push_back(atStart(stringField<S>(
      "world_frame", &S::world_frame, {},
      "frame_id of `~orientation` and `~yaw_plot` (the camera at start or the last reset)")));
  f.push_back(atStart(stringField<S>("tf_child_frame", &S::tf_child_frame, {}, "child frame of the tf broadcast")));
  f.push_back(plotField(doubleField<P>("plot_window", &P::window, 0.1, 3600.0, "s",
                                       "yaw plot: time span shown (longer runs scroll)")));
  f.push_back(plotField(doubleField<P>("plot_width", &P::width, 0.1, 1000.0, "m",
                                       "yaw plot: length of the time axis in `world_frame`")));
  f.push_back(plotField(doubleField<P>("plot_height", &P::height, 0.1, 1000.0, "m",
                                       "yaw plot: height of each panel (yaw, yaw rate)")));
  f.push_back(plotField(intField<P>("plot_points", &P::max_points, 2, 1000000, "", "yaw plot: points kept per line")));
  f.push_back(plotField(doubleField<P>("ground_truth_tolerance", &P::truth_tolerance, 0.0, 10.0, "s",
                                       "a ground-truth pose this close to an image stamp is the plot's reference")));
  f.push_back(atStart(withSpecial(doubleField<S>("fx", &S::fx, 1.0, 1e6, "px",
                                                 "focal length without camera_info; must be set then"),
                                  0.0, "not set")));
  f.push_back(atStart(withSpecial(doubleField<S>("fy", &S::fy, 1.0, 1e6, "px", "focal length without camera_info"),
                                  -1.0, "`fx`")));
  f.push_back(atStart(withSpecial(doubleField<S>("cx", &S::cx, 0.0, 1e6, "px", "principal point without camera_info"),
                                  -1.0, "the image centre")));
  f.push_back(atStart(withSpecial(doubleField<S>("cy", &S::cy, 0.0, 1e6, "px", "principal point without camera_info"),
                                  -1.0, "the image centre")));
  f.push_back(atStart(stringField<S>("distortion_model", &S::distortion_model,
                                     {"none", "plumb_bob", "rational_polynomial", "radtan", "equidistant"},
                                     "distortion model without camera_info")));
  f.push_back(doubleListField<S>("D", &S::D, -1e6, 1e6, "",
                                 "distortion coefficients without camera_info, in the model's order (plumb_bob: k1 k2 "
                                 "p1 p2 [k3]; rational_polynomial: k1 k2 p1 p2 k3 k4 k5 k6; equidistant: k1 k2 k3 k4)"));
  f.push_back(atStart(withSpecial(
      intField<S>("mono16_bit_depth", &S::mono16_bit_depth, 8, 16, "",
                  "mono16 images: the camera's bit depth, a constant scale (brighter values saturate)"),
      0.0, "each frame scaled by its own largest value")));
  return f;
}

}  // namespace

const std::vector<SettingField<NodeSettings>>& nodeSettingFields() {
  static const std::vector<Field> fields = makeFields();
  return fields;
}

const SettingField<NodeSettings>* findNodeSetting(const std::string& name) {
  for (const auto& f : nodeSettingFields())
    if (f.name == name) return &f;
  return nullptr;
}

std::string applyNodeSetting(NodeSettings* settings, const std::string& name, const std::string& value) {
  return applyField(settings, nodeSettingFields(), name, value);
}

std::string validateNodeSettings(const NodeSettings& settings) { return checkRanges(settings, nodeSettingFields()); }

std::vector<AnySetting> everySetting() {
  std::vector<AnySetting> all;
  const NodeSettings node_defaults;
  for (const auto& f : nodeSettingFields()) all.push_back({&f, f.text(node_defaults), true});
  const VisualGyroSettings defaults;
  for (const auto& f : visualGyroSettingFields()) all.push_back({&f, f.text(defaults), false});
  return all;
}

AnySetting findAnySetting(const std::string& name) {
  if (const auto* f = findNodeSetting(name)) return {f, f->text(NodeSettings()), true};
  if (const auto* f = findSetting(name)) return {f, f->text(VisualGyroSettings()), false};
  return {};
}

std::string checkSettingValue(const std::string& name, const std::string& value) {
  if (findNodeSetting(name) != nullptr) {
    NodeSettings scratch;
    return applyNodeSetting(&scratch, name, value);
  }
  VisualGyroSettings scratch;
  return applySetting(&scratch, name, value);
}

}  // namespace visual_gyro
