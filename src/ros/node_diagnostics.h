// Health bookkeeping of the visual_gyro nodelet and the /diagnostics status built from it.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <diagnostic_updater/DiagnosticStatusWrapper.h>

namespace visual_gyro {

/// Counts what happens to the node's input between two diagnostics updates (the window) and in
/// total, and turns them into one status that says why outputs are missing: ERROR for an unusable
/// camera or settings; WARN when input arrives but nothing (or too little) is published, naming
/// the cause (no camera_info, reset storm, skipped or invalid frames); OK otherwise. Rates follow
/// diagnostic_updater::TopicDiagnostic: the expected rate (from the image stamps) beside the
/// measured rates of images in and estimates out. Not thread-safe: the nodelet calls it under its
/// state mutex. Times are wall-clock seconds.
class NodeDiagnostics {
 public:
  /// What the status reports besides the counts.
  struct Context {
    bool subscribed = false;          ///< inputs subscribed (an output has a subscriber)
    std::string image_topic, info_topic;
    std::string method, backend_requested, backend_used, backend_warning;
  };

  explicit NodeDiagnostics(double now = 0.0) : window_start_(now) {}

  /// A (synchronized) image reached the node; `stamp` is its header stamp [s].
  void imageIn(double stamp);
  /// Images and camera_info messages seen by the node's unsynchronized probe since the last
  /// update (the probe runs while no synchronized pair arrives; see the nodelet's updateProbe).
  void probedInput(uint64_t images, uint64_t infos);
  /// A frame was not processed, for `reason` (a short key, shown as "Skipped: <reason>").
  void skipped(const std::string& reason);
  /// The state was reset (previous frame, orientation, plot forgotten) because of `cause`.
  void reset(const std::string& cause);
  /// A frame went through the pipeline.
  void processed() { ++window_.processed; }
  /// A RotationEstimate was published: its validity, status, latency [ms], matches and the ratio
  /// of winning votes to accepted hypotheses.
  void estimatePublished(bool valid, const std::string& status, double latency_ms, int matches,
                         double vote_ratio);
  /// An Imu was published.
  void imuPublished();
  /// Why the current camera model is unusable; "" clears it.
  void setCameraProblem(const std::string& problem) { camera_problem_ = problem; }
  /// Why the settings are unusable; "" clears it.
  void setSettingsProblem(const std::string& problem) { settings_problem_ = problem; }
  const std::string& cameraProblem() const { return camera_problem_; }
  const std::string& settingsProblem() const { return settings_problem_; }

  /// Fills `status` with the window since the last call (then starts a new window) and totals.
  void fill(diagnostic_updater::DiagnosticStatusWrapper& status, double now, const Context& context);

  uint64_t totalImages() const { return total_images_; }
  uint64_t totalEstimates() const { return total_estimates_; }
  uint64_t totalResets() const { return total_resets_; }

 private:
  struct Window {
    uint64_t images = 0, probed_images = 0, unpaired_images = 0, infos = 0, processed = 0, estimates = 0, imus = 0;
    uint64_t invalid = 0, skipped = 0, resets = 0;
    double latency_sum_ms = 0.0, latency_max_ms = 0.0, matches_sum = 0.0, vote_ratio_sum = 0.0;
    std::vector<double> stamp_steps;  ///< differences of consecutive image stamps [s]
  };
  Window window_;
  double window_start_ = 0.0;
  bool have_last_stamp_ = false;
  double last_stamp_ = 0.0;
  uint64_t total_images_ = 0, total_estimates_ = 0, total_imus_ = 0, total_invalid_ = 0;
  uint64_t total_resets_ = 0;
  std::map<std::string, uint64_t> skipped_;  ///< reason -> frames
  std::string last_skip_reason_, last_invalid_reason_, last_reset_cause_;
  std::string camera_problem_, settings_problem_;
};

}  // namespace visual_gyro
