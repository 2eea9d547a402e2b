// The yaw plot of the visual_gyro nodelet: a strip chart drawn with rviz markers (lines, axes,
// ticks, text labels and a legend) of the integrated yaw of the estimate and of the ground truth,
// and of their yaw rates, over a scrolling time window.
#pragma once

#include <deque>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <visualization_msgs/MarkerArray.h>

#include "yaw_plot_settings.h"

namespace visual_gyro {

/// One numeric axis: range and tick step, in the series' unit.
struct PlotAxis {
  double min = 0.0, max = 1.0, step = 0.5;
};

/// Strip chart of yaw [deg] (integrated since the first image, unwrapped) and yaw rate [deg/s]
/// (mean over each interval between two samples, drawn at the interval's midpoint) against time
/// [s] since the first image, for the estimate (green) and the ground truth (red). Yaw is the
/// rotation about the camera optical frame's y axis (down), so a right turn is positive.
///
/// Layout in `frame_id` (rviz x right, y up when viewed from above): the yaw panel spans
/// x in [left, left + width], y in [0, height]; the rate panel lies below it, three text heights
/// lower. The ground-truth lines are wider and drawn under the estimate, so both stay visible
/// where they coincide.
/// The y ranges follow the data in the window (nice tick steps); the time axis shows
/// [0, window] until the data reaches its end, then scrolls.
class YawPlot {
 public:
  enum Panel { kYaw = 0, kRate = 1 };

  explicit YawPlot(const YawPlotSettings& settings = YawPlotSettings());

  const YawPlotSettings& settings() const { return settings_; }
  /// Starts over: the next estimate is time 0 and yaw 0 (the recent ground truth is kept, since the
  /// pose of that next image may already have arrived).
  void reset();

  /// Adds the integrated camera orientation (camera -> start frame) of the image at `stamp` [s].
  /// The first call sets time 0. Stamps that do not increase are ignored.
  void addEstimate(double stamp, const Eigen::Matrix3d& integrated);
  /// Adds a ground-truth orientation (camera -> world) at `stamp` [s]. Its yaw is measured from the
  /// pose at the first image's stamp (within truth_tolerance), so both lines start at 0; the last
  /// poses are kept, so one that comes before its image still serves.
  void addTruth(double stamp, const Eigen::Quaterniond& orientation);

  /// True when there is anything to draw.
  bool empty() const { return estimate_.empty(); }
  /// Number of points of the estimate / ground-truth series in the yaw panel.
  size_t estimatePoints() const { return estimate_.size(); }
  size_t truthPoints() const { return truth_.size(); }

  /// Time axis [s since the first image], and the y axis of a panel ([deg] or [deg/s]).
  PlotAxis timeAxis() const;
  PlotAxis valueAxis(Panel panel) const;
  /// Where a (time [s since start], value) point of `panel` is drawn, in frame_id [m].
  Eigen::Vector2d toPlot(Panel panel, double time, double value) const;
  /// The inverse of toPlot for the value: the value drawn at height y [m] in `panel`.
  double valueAt(Panel panel, double y) const;

  /// Every marker of the plot, led by a DELETEALL so that labels of a scrolled axis disappear.
  /// Namespaces: yaw_estimate, yaw_ground_truth, rate_estimate, rate_ground_truth (LINE_STRIP),
  /// axes (LINE_LIST), labels (TEXT_VIEW_FACING), legend.
  visualization_msgs::MarkerArray markers(double stamp) const;

  /// A "nice" tick step (1, 2 or 5 times a power of ten) giving about `ticks` intervals over `span`.
  static double niceStep(double span, int ticks);

 private:
  struct Sample {
    double t;      ///< [s since start]
    double value;  ///< [deg]
  };
  void trim();
  void pushTruth(double stamp, const Eigen::Quaterniond& orientation);
  static std::vector<Sample> rates(const std::deque<Sample>& yaw);
  /// markers()' panel frames, value and time ticks, grid lines and labels (namespaces axes and
  /// labels), stamped `time`.
  void addAxes(const ros::Time& time, visualization_msgs::MarkerArray* array) const;
  /// markers()' line of `samples` in `panel` (ns/id, colour, line width [m], height z [m] above
  /// the plot), clipped to the time window: the point left of it is moved onto its edge. Nothing
  /// without a point in the window.
  void addSeries(const ros::Time& time, const std::string& ns, int id, Panel panel, const std::vector<Sample>& samples,
                 const std_msgs::ColorRGBA& colour, double line_width, double z,
                 visualization_msgs::MarkerArray* array) const;
  /// markers()' legend above the yaw panel's right end; the ground-truth entry only when there is
  /// truth.
  void addLegend(const ros::Time& time, visualization_msgs::MarkerArray* array) const;

  YawPlotSettings settings_;
  bool started_ = false;
  double t0_ = 0.0;
  std::deque<Sample> estimate_, truth_;
  double estimate_last_yaw_ = 0.0;
  bool have_truth_reference_ = false;
  Eigen::Quaterniond truth_reference_ = Eigen::Quaterniond::Identity();
  double truth_last_yaw_ = 0.0;
  std::deque<std::pair<double, Eigen::Quaterniond>> recent_truth_;  ///< the last poses, for a (re)start
};

}  // namespace visual_gyro
