#include "node_diagnostics.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <diagnostic_msgs/DiagnosticStatus.h>

namespace visual_gyro {

namespace {

using Level = diagnostic_msgs::DiagnosticStatus;

unsigned long long ull(uint64_t v) { return static_cast<unsigned long long>(v); }

double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  return values[mid];
}

}  // namespace

void NodeDiagnostics::start(double now) {
  std::lock_guard<std::mutex> lock(mutex_);
  window_ = Window();
  window_start_ = now;
}

void NodeDiagnostics::processed() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++window_.processed;
}

void NodeDiagnostics::setCameraProblem(const std::string& problem) {
  std::lock_guard<std::mutex> lock(mutex_);
  camera_problem_ = problem;
}

void NodeDiagnostics::setSettingsProblem(const std::string& problem) {
  std::lock_guard<std::mutex> lock(mutex_);
  settings_problem_ = problem;
}

void NodeDiagnostics::setRejectedChange(const std::string& why) {
  std::lock_guard<std::mutex> lock(mutex_);
  rejected_change_ = why;
}

void NodeDiagnostics::setBackend(std::optional<Backend> used, const std::string& warning) {
  std::lock_guard<std::mutex> lock(mutex_);
  backend_used_ = used;
  backend_warning_ = warning;
}

std::string NodeDiagnostics::cameraProblem() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return camera_problem_;
}

std::string NodeDiagnostics::settingsProblem() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return settings_problem_;
}

std::string NodeDiagnostics::rejectedChange() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return rejected_change_;
}

uint64_t NodeDiagnostics::totalImages() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return total_images_;
}

uint64_t NodeDiagnostics::totalEstimates() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return total_estimates_;
}

uint64_t NodeDiagnostics::totalResets() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return total_resets_;
}

void NodeDiagnostics::imageIn(double stamp) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++window_.images;
  ++total_images_;
  // The expected rate comes from the stamps, so that it does not depend on how fast images are
  // delivered; only forward steps count (a jump back is a reset, not a frame interval).
  if (have_last_stamp_ && stamp > last_stamp_) {
    window_.stamp_steps.push_back(stamp - last_stamp_);
    recent_steps_.push_back(stamp - last_stamp_);
    if (recent_steps_.size() > kIntervalSteps) recent_steps_.pop_front();
  }
  have_last_stamp_ = true;
  last_stamp_ = stamp;
}

void NodeDiagnostics::probedInput(uint64_t images, uint64_t infos) {
  std::lock_guard<std::mutex> lock(mutex_);
  window_.probed_images += images;
  window_.infos += infos;
}

void NodeDiagnostics::skipped(const std::string& reason) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++skipped_[reason];
  ++window_.skipped;
  last_skip_reason_ = reason;
}

void NodeDiagnostics::reset(const std::string& cause) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++window_.resets;
  ++total_resets_;
  last_reset_cause_ = cause;
}

void NodeDiagnostics::noTexture(const std::string& reason) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++window_.no_texture;
  ++total_no_texture_;
  last_no_texture_reason_ = reason;
}

void NodeDiagnostics::setCalibrationMismatch(const std::string& why) {
  std::lock_guard<std::mutex> lock(mutex_);
  calibration_mismatch_ = why;
}

std::string NodeDiagnostics::calibrationMismatch() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return calibration_mismatch_;
}

void NodeDiagnostics::estimatePublished(bool valid, const std::string& status, double latency_ms,
                                        int matches, double vote_ratio, bool half_resolution) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++window_.estimates;
  ++total_estimates_;
  window_.latency_sum_ms += latency_ms;
  window_.latency_max_ms = std::max(window_.latency_max_ms, latency_ms);
  window_.matches_sum += matches;
  window_.vote_ratio_sum += vote_ratio;
  if (half_resolution) ++window_.half_resolution;
  if (!valid) {
    ++window_.invalid;
    ++total_invalid_;
    last_invalid_reason_ = status;
  }
}

void NodeDiagnostics::imuPublished() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++window_.imus;
  ++total_imus_;
}

void NodeDiagnostics::fill(diagnostic_updater::DiagnosticStatusWrapper& status, double now,
                           const Context& context) {
  std::lock_guard<std::mutex> lock(mutex_);
  const double span = std::max(now - window_start_, 1e-3);
  Window w = window_;
  // The probe sees paired images too (it runs until pairs come); the surplus had no camera_info.
  w.unpaired_images = w.probed_images > w.images ? w.probed_images - w.images : 0;
  window_ = Window();
  window_start_ = now;
  recent_.push_back(RecentWindow{now, w.images, w.resets});
  while (!recent_.empty() && recent_.front().end <= now - kRecentSpanS) recent_.pop_front();
  addValues(status, w, span, context);
  summarize(status, w, span, context);
}

void NodeDiagnostics::addValues(diagnostic_updater::DiagnosticStatusWrapper& status, const Window& w,
                                double span, const Context& context) const {
  const double step = median(w.stamp_steps);
  const double estimates = static_cast<double>(w.estimates);
  status.add("Subscribed", context.subscribed ? "yes" : "no (no output subscribers)");
  status.add("Expected rate [Hz] (image stamps)", step > 0.0 ? 1.0 / step : 0.0);
  status.add("Images in [Hz]", w.images / span);
  status.add("Estimates out [Hz]", w.estimates / span);
  status.add("Valid estimates out [Hz]", (w.estimates - w.invalid) / span);
  status.add("Imu out [Hz]", w.imus / span);
  status.add("Images without camera_info [Hz]", w.unpaired_images / span);
  status.add("Latency mean [ms]", w.estimates > 0 ? w.latency_sum_ms / estimates : 0.0);
  status.add("Latency max [ms]", w.latency_max_ms);
  status.add("Matches (mean)", w.estimates > 0 ? w.matches_sum / estimates : 0.0);
  status.add("Winning vote ratio (mean)", w.estimates > 0 ? w.vote_ratio_sum / estimates : 0.0);
  // Many pairs at half resolution: the camera blurs most images (exposure too long for the motion).
  status.add("Half-resolution pairs [%]",
             w.estimates > 0 ? 100.0 * static_cast<double>(w.half_resolution) / estimates : 0.0);
  status.add("Method", context.method.empty() ? std::string("?") : context.method);
  status.add("Backend requested", context.backend_requested);
  const std::optional<Backend> backend_used = backendInUse(context);
  const std::string& backend_warning = context.backend_warning.empty() ? backend_warning_ : context.backend_warning;
  status.add("Backend", backend_used ? std::string(backendName(*backend_used)) : std::string("(not started: no image yet)"));
  if (!backend_warning.empty()) status.add("Backend warning", backend_warning);
  status.add("Images received", total_images_);
  status.add("Estimates published", total_estimates_);
  status.add("Imu published", total_imus_);
  status.add("Invalid estimates", total_invalid_);
  status.add("Images without texture", total_no_texture_);
  status.add("Resets", total_resets_);
  if (!last_reset_cause_.empty()) status.add("Last reset", last_reset_cause_);
  uint64_t skipped_total = 0;
  for (const auto& entry : skipped_) {
    status.add("Skipped: " + entry.first, entry.second);
    skipped_total += entry.second;
  }
  status.add("Skipped frames", skipped_total);
  if (!camera_problem_.empty()) status.add("Camera problem", camera_problem_);
  if (!calibration_mismatch_.empty()) status.add("Calibration mismatch", calibration_mismatch_);
  if (!settings_problem_.empty()) status.add("Settings problem", settings_problem_);
  if (!rejected_change_.empty()) status.add("Rejected settings change", rejected_change_);
}

std::optional<Backend> NodeDiagnostics::backendInUse(const Context& context) const {
  return context.backend_used ? context.backend_used : backend_used_;
}

std::string NodeDiagnostics::slowCameraWarning(const Context& context, uint64_t recent_resets) const {
  if (!(context.max_gap > 0.0) || recent_resets == 0 || recent_steps_.size() < 2) return "";
  const double interval = median(std::vector<double>(recent_steps_.begin(), recent_steps_.end()));
  if (!(interval > context.max_gap)) return "";
  // 20 % above the interval, so that the cameras' jitter does not reset either; rounded up to
  // 0.1 s.
  constexpr double kIntervalMargin = 1.2;
  const double suggested = std::ceil(kIntervalMargin * interval * 10.0 - 1e-9) / 10.0;
  char text[256];
  std::snprintf(text, sizeof(text),
                "the camera's interval of %.3g s (%.2g Hz) exceeds max_gap (%.3g s): every frame resets the "
                "state, no output; set max_gap to at least %.1f s",
                interval, 1.0 / interval, context.max_gap, suggested);
  return text;
}

void NodeDiagnostics::summarize(diagnostic_updater::DiagnosticStatusWrapper& status, const Window& w, double span,
                                const Context& context) const {
  uint64_t recent_images = 0, recent_resets = 0;
  for (const RecentWindow& r : recent_) {
    recent_images += r.images;
    recent_resets += r.resets;
  }
  const double step = median(w.stamp_steps);
  const double expected_hz = step > 0.0 ? 1.0 / step : 0.0;
  const double images_hz = w.images / span;
  const double estimates_hz = w.estimates / span;
  const double valid_hz = (w.estimates - w.invalid) / span;
  const double mean_latency = w.estimates > 0 ? w.latency_sum_ms / w.estimates : 0.0;
  const std::optional<Backend> backend_used = backendInUse(context);
  const std::string slow_camera = slowCameraWarning(context, recent_resets);
  // A storm: resets at a quarter of the images or more (at least kMinStormResets) within the
  // recent span. A bag replayed in a loop resets once per loop; far fewer.
  constexpr uint64_t kMinStormResets = 3;
  const bool storm = recent_resets >= kMinStormResets && 4 * recent_resets >= recent_images;

  // The first matching line is the summary, most severe first.
  const bool input = w.images > 0 || w.unpaired_images > 0;
  if (!settings_problem_.empty()) {
    status.summary(Level::ERROR, "settings unusable, no output: " + settings_problem_);
  } else if (!camera_problem_.empty() && w.processed == 0 && input) {
    status.summary(Level::ERROR, "camera unusable, no output: " + camera_problem_);
  } else if (!rejected_change_.empty()) {
    status.summary(Level::WARN, "rejected settings change: " + rejected_change_);
  } else if (w.unpaired_images > 0 && w.images == 0) {
    status.summaryf(Level::WARN, "%llu image(s) on %s but %s, no output",
                    ull(w.unpaired_images), context.image_topic.c_str(),
                    w.infos == 0 ? ("no camera_info on " + context.info_topic).c_str()
                                 : "no camera_info with the same stamp (stamps differ)");
  } else if (!slow_camera.empty()) {
    status.summary(Level::WARN, slow_camera);
  } else if (storm) {
    status.summaryf(Level::WARN, "reset storm: %llu resets for %llu images in the last %.0f s (last: %s), %.1f Hz out",
                    ull(recent_resets), ull(recent_images), kRecentSpanS, last_reset_cause_.c_str(), valid_hz);
  } else if (w.no_texture > 0 && 2 * w.no_texture >= w.images) {
    status.summaryf(Level::WARN, "no texture in %llu of %llu image(s) (last: %s), no output from them",
                    ull(w.no_texture), ull(w.images), last_no_texture_reason_.c_str());
  } else if (!calibration_mismatch_.empty()) {
    status.summary(Level::WARN, "calibration does not fit the images, covariance inflated: " + calibration_mismatch_);
  } else if (w.skipped > 0) {
    status.summaryf(Level::WARN, "%llu of %llu frame(s) skipped (last: %s), %.1f Hz out",
                    ull(w.skipped), ull(w.images), last_skip_reason_.c_str(), valid_hz);
  } else if (w.estimates > 0 && 2 * w.invalid > w.estimates) {
    status.summaryf(Level::WARN, "%llu of %llu estimates invalid (last: %s)", ull(w.invalid),
                    ull(w.estimates), last_invalid_reason_.c_str());
  } else if (w.images >= 3 && 2 * w.estimates < w.images) {
    // Every frame after the first gives an estimate; fewer means frames are lost in the node.
    status.summaryf(Level::WARN, "%.1f Hz of images in but only %.1f Hz of estimates out",
                    images_hz, estimates_hz);
  } else if (!context.subscribed) {
    status.summary(Level::OK, "idle: no output subscribers");
  } else if (!input) {
    status.summary(Level::OK, "subscribed, waiting for images");
  } else {
    status.summaryf(Level::OK, "%.1f Hz out (expected %.1f Hz), %.1f ms latency, backend %s",
                    valid_hz, expected_hz, mean_latency, backend_used ? backendName(*backend_used) : "");
  }
}

}  // namespace visual_gyro
