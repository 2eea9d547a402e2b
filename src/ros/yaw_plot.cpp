#include "yaw_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "visual_gyro/geometry.h"

namespace visual_gyro {

namespace {

// Smallest y span of a panel: a nearly constant line is not magnified into noise.
constexpr double kMinYawSpanDeg = 10.0;
constexpr double kMinRateSpanDps = 10.0;

std_msgs::ColorRGBA rgba(float r, float g, float b, float a = 1.0f) {
  std_msgs::ColorRGBA c;
  c.r = r;
  c.g = g;
  c.b = b;
  c.a = a;
  return c;
}

const std_msgs::ColorRGBA kEstimateColour = rgba(0.1f, 0.9f, 0.1f);
const std_msgs::ColorRGBA kTruthColour = rgba(0.9f, 0.2f, 0.1f);
const std_msgs::ColorRGBA kAxisColour = rgba(0.85f, 0.85f, 0.85f);
const std_msgs::ColorRGBA kGridColour = rgba(0.6f, 0.6f, 0.6f, 0.35f);
const std_msgs::ColorRGBA kTextColour = rgba(0.95f, 0.95f, 0.95f);

geometry_msgs::Point point(const Eigen::Vector2d& p) {
  geometry_msgs::Point q;
  q.x = p.x();
  q.y = p.y();
  return q;
}

/// Tick label: no trailing ".0", no "-0".
std::string tickText(double value, double step) {
  char buf[32];
  const int decimals = step >= 1.0 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  if (std::abs(value) < 0.5 * step * 1e-6) value = 0.0;
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, value);
  return buf;
}

}  // namespace

YawPlot::YawPlot(const YawPlotSettings& settings) : settings_(settings) {
  settings_.window = std::max(settings_.window, 1e-3);
  settings_.width = std::max(settings_.width, 1e-3);
  settings_.height = std::max(settings_.height, 1e-3);
  settings_.max_points = std::max(settings_.max_points, 2);
}

void YawPlot::reset() {
  // The recent truth stays: after a loop or a gap the pose of the new first image may have come
  // before the image.
  started_ = false;
  estimate_.clear();
  truth_.clear();
  estimate_last_yaw_ = 0.0;
  have_truth_reference_ = false;
  truth_last_yaw_ = 0.0;
}

void YawPlot::addEstimate(double stamp, const Eigen::Matrix3d& integrated) {
  if (!started_) {
    started_ = true;
    t0_ = stamp;
    estimate_.clear();
    truth_.clear();
    estimate_last_yaw_ = 0.0;
    have_truth_reference_ = false;
    // Ground truth may come before the image: take the reference (and what follows) from there.
    for (const auto& entry : recent_truth_) pushTruth(entry.first, entry.second);
  }
  const double t = stamp - t0_;
  if (!estimate_.empty() && t <= estimate_.back().t) return;
  const double yaw = unwrapAngleDeg(yawPitchRollFromRotation(integrated)[0] * kRadToDeg, estimate_last_yaw_);
  estimate_last_yaw_ = yaw;
  estimate_.push_back({t, yaw});
  trim();
}

void YawPlot::addTruth(double stamp, const Eigen::Quaterniond& orientation) {
  // Kept for the next start (its first image's stamp picks the reference); a jump back starts over.
  if (!recent_truth_.empty() && stamp < recent_truth_.back().first) recent_truth_.clear();
  recent_truth_.emplace_back(stamp, orientation);
  while (recent_truth_.size() > 200) recent_truth_.pop_front();
  if (!started_) return;
  pushTruth(stamp, orientation);
  trim();
}

void YawPlot::pushTruth(double stamp, const Eigen::Quaterniond& orientation) {
  const double t = stamp - t0_;
  if (!have_truth_reference_) {
    if (std::abs(t) > settings_.truth_tolerance) return;
    have_truth_reference_ = true;
    truth_reference_ = orientation;
    truth_last_yaw_ = 0.0;
  }
  if (t < -settings_.truth_tolerance || (!truth_.empty() && t <= truth_.back().t)) return;
  const Eigen::Matrix3d relative = truth_reference_.toRotationMatrix().transpose() * orientation.toRotationMatrix();
  const double yaw = unwrapAngleDeg(yawPitchRollFromRotation(relative)[0] * kRadToDeg, truth_last_yaw_);
  truth_last_yaw_ = yaw;
  truth_.push_back({t, yaw});
}

void YawPlot::trim() {
  // Keep one point left of the window so the lines reach its left edge.
  const double latest = std::max(estimate_.empty() ? 0.0 : estimate_.back().t, truth_.empty() ? 0.0 : truth_.back().t);
  const double left = latest - settings_.window;
  for (std::deque<Sample>* series : {&estimate_, &truth_}) {
    while (series->size() > 2 && (*series)[1].t < left) series->pop_front();
    while (static_cast<int>(series->size()) > settings_.max_points) series->pop_front();
  }
}

std::vector<YawPlot::Sample> YawPlot::rates(const std::deque<Sample>& yaw) {
  std::vector<Sample> out;
  for (size_t i = 1; i < yaw.size(); ++i) {
    const double dt = yaw[i].t - yaw[i - 1].t;
    if (dt > 0.0) out.push_back({0.5 * (yaw[i].t + yaw[i - 1].t), (yaw[i].value - yaw[i - 1].value) / dt});
  }
  return out;
}

double YawPlot::niceStep(double span, int ticks) {
  if (!(span > 0.0) || ticks < 1) return 1.0;
  const double raw = span / ticks;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  const double fraction = raw / magnitude;
  // The nearest of 1, 2, 5, 10 (so about `ticks` intervals, never far fewer).
  const double nice = fraction < 1.5 ? 1.0 : fraction < 3.0 ? 2.0 : fraction < 7.0 ? 5.0 : 10.0;
  return nice * magnitude;
}

PlotAxis YawPlot::timeAxis() const {
  double latest = 0.0;
  if (!estimate_.empty()) latest = estimate_.back().t;
  if (!truth_.empty()) latest = std::max(latest, truth_.back().t);
  PlotAxis axis;
  axis.min = std::max(0.0, latest - settings_.window);
  axis.max = axis.min + settings_.window;
  axis.step = niceStep(settings_.window, 5);
  return axis;
}

PlotAxis YawPlot::valueAxis(Panel panel) const {
  const PlotAxis time = timeAxis();
  double lo = 0.0, hi = 0.0;
  bool any = false;
  auto include = [&](double t, double v) {
    if (t < time.min || t > time.max || !std::isfinite(v)) return;
    lo = any ? std::min(lo, v) : v;
    hi = any ? std::max(hi, v) : v;
    any = true;
  };
  for (const std::deque<Sample>* series : {&estimate_, &truth_}) {
    if (panel == kYaw) {
      for (const Sample& s : *series) include(s.t, s.value);
    } else {
      for (const Sample& s : rates(*series)) include(s.t, s.value);
    }
  }
  if (!any) lo = hi = 0.0;
  const double min_span = panel == kYaw ? kMinYawSpanDeg : kMinRateSpanDps;
  if (hi - lo < min_span) {
    const double mid = 0.5 * (hi + lo);
    lo = mid - 0.5 * min_span;
    hi = mid + 0.5 * min_span;
  }
  PlotAxis axis;
  axis.step = niceStep(hi - lo, 4);
  axis.min = std::floor(lo / axis.step) * axis.step;
  axis.max = std::ceil(hi / axis.step) * axis.step;
  if (axis.max - axis.min < axis.step) axis.max = axis.min + axis.step;
  return axis;
}

Eigen::Vector2d YawPlot::toPlot(Panel panel, double time, double value) const {
  const PlotAxis t = timeAxis();
  const PlotAxis v = valueAxis(panel);
  const double bottom = panel == kYaw ? 0.0 : -(settings_.height + 3.0 * settings_.text_size);
  return Eigen::Vector2d(settings_.left + (time - t.min) / (t.max - t.min) * settings_.width,
                         bottom + (value - v.min) / (v.max - v.min) * settings_.height);
}

double YawPlot::valueAt(Panel panel, double y) const {
  const PlotAxis v = valueAxis(panel);
  const double bottom = panel == kYaw ? 0.0 : -(settings_.height + 3.0 * settings_.text_size);
  return v.min + (y - bottom) / settings_.height * (v.max - v.min);
}

namespace {

/// A marker of the plot in `frame_id` at `time`: added, unrotated, unit scale, axis colour.
visualization_msgs::Marker plotMarker(const std::string& frame_id, const ros::Time& time, const std::string& ns,
                                      int id, int type) {
  visualization_msgs::Marker m;
  m.header.frame_id = frame_id;
  m.header.stamp = time;
  m.ns = ns;
  m.id = id;
  m.type = type;
  m.action = visualization_msgs::Marker::ADD;
  m.pose.orientation.w = 1.0;
  m.scale.x = m.scale.y = m.scale.z = 1.0;
  m.color = kAxisColour;
  return m;
}

/// Approximate half width [m] of a label of text height `size` [m]: rviz centres text on its
/// position.
double labelHalfWidth(const std::string& s, double size) { return 0.3 * size * static_cast<double>(s.size()); }

/// Appends the segment a-b to a LINE_LIST marker.
void addLine(visualization_msgs::Marker* m, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  m->points.push_back(point(a));
  m->points.push_back(point(b));
}

}  // namespace

visualization_msgs::MarkerArray YawPlot::markers(double stamp) const {
  visualization_msgs::MarkerArray array;
  ros::Time time;
  time.fromSec(std::max(stamp, 0.0));
  visualization_msgs::Marker clear;
  clear.header.frame_id = settings_.frame_id;
  clear.header.stamp = time;
  clear.action = visualization_msgs::Marker::DELETEALL;
  clear.pose.orientation.w = 1.0;
  array.markers.push_back(clear);
  if (empty()) return array;

  addAxes(time, &array);
  const std::vector<Sample> estimate(estimate_.begin(), estimate_.end());
  const std::vector<Sample> truth(truth_.begin(), truth_.end());
  // Truth wide and underneath, the estimate narrow on top (z towards a viewer from above).
  addSeries(time, "yaw_estimate", 0, kYaw, estimate, kEstimateColour, 0.03, 0.02, &array);
  addSeries(time, "yaw_ground_truth", 1, kYaw, truth, kTruthColour, 0.08, 0.01, &array);
  addSeries(time, "rate_estimate", 2, kRate, rates(estimate_), kEstimateColour, 0.03, 0.02, &array);
  addSeries(time, "rate_ground_truth", 3, kRate, rates(truth_), kTruthColour, 0.08, 0.01, &array);
  addLegend(time, &array);
  return array;
}

void YawPlot::addAxes(const ros::Time& time, visualization_msgs::MarkerArray* array) const {
  const double size = settings_.text_size;
  int label_id = 0;
  auto text = [&](const std::string& s, const Eigen::Vector2d& at) {
    visualization_msgs::Marker m =
        plotMarker(settings_.frame_id, time, "labels", label_id++, visualization_msgs::Marker::TEXT_VIEW_FACING);
    m.pose.position.x = at.x();
    m.pose.position.y = at.y();
    m.scale.x = m.scale.y = m.scale.z = size;
    m.color = kTextColour;
    m.text = s;
    array->markers.push_back(m);
  };
  auto halfWidth = [size](const std::string& s) { return labelHalfWidth(s, size); };

  const PlotAxis t_axis = timeAxis();
  visualization_msgs::Marker axes = plotMarker(settings_.frame_id, time, "axes", 0, visualization_msgs::Marker::LINE_LIST);
  axes.scale.x = 0.015;
  visualization_msgs::Marker grid = plotMarker(settings_.frame_id, time, "axes", 1, visualization_msgs::Marker::LINE_LIST);
  grid.scale.x = 0.01;
  grid.color = kGridColour;

  const char* titles[2] = {"integrated yaw [deg]", "yaw rate [deg/s]"};
  for (Panel panel : {kYaw, kRate}) {
    const PlotAxis v = valueAxis(panel);
    const Eigen::Vector2d lower_left = toPlot(panel, t_axis.min, v.min);
    const Eigen::Vector2d upper_right = toPlot(panel, t_axis.max, v.max);
    const double x0 = lower_left.x(), x1 = upper_right.x(), y0 = lower_left.y(), y1 = upper_right.y();
    // Frame of the panel.
    addLine(&axes, {x0, y0}, {x1, y0});
    addLine(&axes, {x1, y0}, {x1, y1});
    addLine(&axes, {x1, y1}, {x0, y1});
    addLine(&axes, {x0, y1}, {x0, y0});
    // Value ticks, grid lines and labels.
    const double tick = 0.08;
    for (double value = v.min; value <= v.max + 1e-9 * v.step; value += v.step) {
      const double y = toPlot(panel, t_axis.min, value).y();
      addLine(&axes, {x0 - tick, y}, {x0, y});
      if (value > v.min + 1e-9 * v.step && value < v.max - 1e-9 * v.step) addLine(&grid, {x0, y}, {x1, y});
      const std::string s = tickText(value, v.step);
      text(s, {x0 - tick - 0.05 - halfWidth(s), y});
    }
    // Time ticks on both panels, labels under each.
    const double first = std::ceil(t_axis.min / t_axis.step - 1e-9) * t_axis.step;
    for (double tt = first; tt <= t_axis.max + 1e-9 * t_axis.step; tt += t_axis.step) {
      const double x = toPlot(panel, tt, v.min).x();
      addLine(&axes, {x, y0 - tick}, {x, y0});
      if (tt > t_axis.min + 1e-9 && tt < t_axis.max - 1e-9) addLine(&grid, {x, y0}, {x, y1});
      text(tickText(tt, t_axis.step), {x, y0 - tick - 0.7 * size});
    }
    text(titles[panel], {x0 + halfWidth(titles[panel]), y1 + 0.8 * size});
    text("time [s]", {x1 - halfWidth("time [s]"), y0 - tick - 1.9 * size});
  }
  array->markers.push_back(axes);
  array->markers.push_back(grid);
}

void YawPlot::addSeries(const ros::Time& time, const std::string& ns, int id, Panel panel,
                        const std::vector<Sample>& samples, const std_msgs::ColorRGBA& colour, double line_width,
                        double z, visualization_msgs::MarkerArray* array) const {
  const PlotAxis t_axis = timeAxis();
  visualization_msgs::Marker m = plotMarker(settings_.frame_id, time, ns, id, visualization_msgs::Marker::LINE_STRIP);
  m.scale.x = line_width;
  m.pose.position.z = z;
  m.color = colour;
  for (size_t i = 0; i < samples.size(); ++i) {
    Sample s = samples[i];
    if (s.t < t_axis.min) {
      if (i + 1 >= samples.size() || samples[i + 1].t <= t_axis.min) continue;
      const Sample& n = samples[i + 1];
      s.value += (n.value - s.value) * (t_axis.min - s.t) / (n.t - s.t);
      s.t = t_axis.min;
    }
    m.points.push_back(point(toPlot(panel, s.t, s.value)));
  }
  // rviz needs two points for a line; a lone point is drawn as a zero-length line.
  if (m.points.size() == 1) m.points.push_back(m.points.front());
  if (!m.points.empty()) array->markers.push_back(m);
}

void YawPlot::addLegend(const ros::Time& time, visualization_msgs::MarkerArray* array) const {
  const double size = settings_.text_size;
  const PlotAxis t_axis = timeAxis();
  const Eigen::Vector2d top_right = toPlot(kYaw, t_axis.max, valueAxis(kYaw).max);
  double x = top_right.x();
  const double y = top_right.y() + 0.8 * size;
  int legend_id = 100;
  auto entry = [&](const std::string& s, const std_msgs::ColorRGBA& colour) {
    x -= 2.0 * labelHalfWidth(s, size);
    visualization_msgs::Marker sample =
        plotMarker(settings_.frame_id, time, "legend", legend_id++, visualization_msgs::Marker::LINE_LIST);
    sample.scale.x = 0.05;
    sample.color = colour;
    addLine(&sample, {x - 0.5, y}, {x - 0.1, y});
    array->markers.push_back(sample);
    visualization_msgs::Marker label =
        plotMarker(settings_.frame_id, time, "legend", legend_id++, visualization_msgs::Marker::TEXT_VIEW_FACING);
    label.pose.position.x = x + labelHalfWidth(s, size);
    label.pose.position.y = y;
    label.scale.x = label.scale.y = label.scale.z = size;
    label.color = colour;
    label.text = s;
    array->markers.push_back(label);
    x -= 0.9;
  };
  if (!truth_.empty()) entry("ground truth", kTruthColour);
  entry("estimate", kEstimateColour);
}

}  // namespace visual_gyro
