// Health bookkeeping of the visual_gyro nodelet and the /diagnostics status built from it.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <diagnostic_updater/DiagnosticStatusWrapper.h>

#include "visual_gyro/backend.h"

namespace visual_gyro {

/// Counts what happens to the node's input between two diagnostics updates (the window) and in
/// total, and turns them into one status that says why outputs are missing: ERROR for an unusable
/// camera or settings; WARN when input arrives but nothing (or too little) is published, naming
/// the cause (no camera_info, a camera slower than max_gap, reset storm, images without texture,
/// a calibration that does not fit the images, skipped or invalid frames); OK otherwise. Causes
/// that show only over several frames (a slow camera, reset storms) are judged over the last
/// kRecentSpanS seconds of windows, not over one window. Rates follow
/// diagnostic_updater::TopicDiagnostic: the expected rate (from the image stamps) beside the
/// measured rates of images in and estimates out. Thread-safe: every call holds the object's own
/// mutex for its few statements only (the innermost lock of the nodelet). Times are wall-clock
/// seconds.
class NodeDiagnostics {
 public:
  /// What the status reports besides the counts.
  struct Context {
    bool subscribed = false;          ///< inputs subscribed (an output has a subscriber)
    std::string image_topic, info_topic;
    std::string method, backend_requested, backend_warning;
    /// The backend in use; empty: the one setBackend() named.
    std::optional<Backend> backend_used;
    double max_gap = 0.0;  ///< [s] the node's ~max_gap (a larger stamp gap resets); 0: unknown
  };

  /// [s] Span of the recent windows over which reset storms and a camera slower than max_gap are
  /// judged: a storm of one reset every second frame at 3 Hz leaves some 1-s windows with a single
  /// reset (and a 0.8 Hz camera many windows with no image at all), but 5 s hold 7 resets.
  static constexpr double kRecentSpanS = 5.0;
  /// Image stamp steps remembered for the camera's interval (across windows).
  static constexpr size_t kIntervalSteps = 8;

  explicit NodeDiagnostics(double now = 0.0) : window_start_(now) {}
  NodeDiagnostics(const NodeDiagnostics&) = delete;
  NodeDiagnostics& operator=(const NodeDiagnostics&) = delete;

  /// Starts the first window at `now`.
  void start(double now);

  /// A (synchronized) image reached the node; `stamp` is its header stamp [s].
  void imageIn(double stamp);
  /// Images and camera_info messages seen by the node's unsynchronized probe since the last
  /// update (the probe runs while no synchronized pair arrives; see the nodelet's updateProbe).
  void probedInput(uint64_t images, uint64_t infos);
  /// A frame was not processed, for `reason` (a short key, shown as "Skipped: <reason>").
  void skipped(const std::string& reason);
  /// The state was reset (previous frame, orientation, plot forgotten) because of `cause`.
  void reset(const std::string& cause);
  /// An image had no texture (FrameStatus::kNoTexture); `reason` says how it looked.
  void noTexture(const std::string& reason);
  /// The calibration check's verdict on the recent frames: "" while the calibration fits the
  /// images (or cannot be judged), else why not (a WARN naming camera_info until cleared).
  void setCalibrationMismatch(const std::string& why);
  /// A frame went through the pipeline.
  void processed();
  /// A RotationEstimate was published: its validity, status, latency [ms], matches, the ratio
  /// of winning votes to accepted hypotheses, and whether its matches came from half resolution.
  void estimatePublished(bool valid, const std::string& status, double latency_ms, int matches,
                         double vote_ratio, bool half_resolution = false);
  /// An Imu was published.
  void imuPublished();
  /// Why the current camera model is unusable; "" clears it.
  void setCameraProblem(const std::string& problem);
  /// Why the settings are unusable (no output at all); "" clears it.
  void setSettingsProblem(const std::string& problem);
  /// Why the last live settings change was rejected (the previous settings stay in use): a WARN
  /// until a later change is accepted, which clears it with "".
  void setRejectedChange(const std::string& why);
  /// The backend in use (empty: not started yet) and its last warning (when the context does not
  /// name them).
  void setBackend(std::optional<Backend> used, const std::string& warning);
  std::string cameraProblem() const;
  std::string calibrationMismatch() const;
  std::string settingsProblem() const;
  std::string rejectedChange() const;

  /// Fills `status` with the window since the last call (then starts a new window) and totals.
  void fill(diagnostic_updater::DiagnosticStatusWrapper& status, double now, const Context& context);

  uint64_t totalImages() const;
  uint64_t totalEstimates() const;
  uint64_t totalResets() const;

 private:
  struct Window {
    uint64_t images = 0, probed_images = 0, unpaired_images = 0, infos = 0, processed = 0, estimates = 0, imus = 0;
    uint64_t invalid = 0, skipped = 0, resets = 0, half_resolution = 0, no_texture = 0;
    double latency_sum_ms = 0.0, latency_max_ms = 0.0, matches_sum = 0.0, vote_ratio_sum = 0.0;
    std::vector<double> stamp_steps;  ///< differences of consecutive image stamps [s]
  };
  /// The key-value pairs of `status`: window `w` (over `span` seconds) and the totals.
  void addValues(diagnostic_updater::DiagnosticStatusWrapper& status, const Window& w, double span,
                 const Context& context) const;
  /// The summary line and level: the most severe cause that applies.
  void summarize(diagnostic_updater::DiagnosticStatusWrapper& status, const Window& w, double span,
                 const Context& context) const;
  /// "" unless the camera's interval (median of recent_steps_) exceeds context.max_gap while the
  /// state was reset recently; then the WARN, with a max_gap that would do.
  std::string slowCameraWarning(const Context& context, uint64_t recent_resets) const;
  /// The backend the context names, else the one setBackend() named; mutex_ held.
  std::optional<Backend> backendInUse(const Context& context) const;

  /// Images and resets of one past window, ending at `end` [s].
  struct RecentWindow {
    double end = 0.0;
    uint64_t images = 0, resets = 0;
  };
  mutable std::mutex mutex_;  ///< guards everything below
  Window window_;
  double window_start_ = 0.0;
  std::deque<RecentWindow> recent_;  ///< windows ending within the last kRecentSpanS, oldest first
  std::deque<double> recent_steps_;  ///< the last kIntervalSteps forward image stamp steps [s]
  bool have_last_stamp_ = false;
  double last_stamp_ = 0.0;
  uint64_t total_images_ = 0, total_estimates_ = 0, total_imus_ = 0, total_invalid_ = 0;
  uint64_t total_resets_ = 0;
  std::map<std::string, uint64_t> skipped_;  ///< reason -> frames
  uint64_t total_no_texture_ = 0;
  std::string last_skip_reason_, last_invalid_reason_, last_reset_cause_, last_no_texture_reason_;
  std::string camera_problem_, settings_problem_, rejected_change_, calibration_mismatch_;
  std::optional<Backend> backend_used_;
  std::string backend_warning_;
};

}  // namespace visual_gyro
