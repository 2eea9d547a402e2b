#include "method_evaluation.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "imu_alignment_report.h"
#include "json_writer.h"
#include "visual_gyro/calibration_fit.h"
#include "visual_gyro/geometry.h"

namespace visual_gyro {
namespace eval {
namespace {

std::string fmt(double v, int decimals = 3) {
  if (!std::isfinite(v)) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

/// The calibration check's figures over the rows: the median correlation and the largest median
/// of a full window, as CalibrationFitMonitor judges them.
void summarizeCalibrationFit(MethodSummary* s) {
  std::vector<double> all;
  CalibrationFitMonitor window;
  for (const FrameRow& row : s->rows) {
    if (!std::isfinite(row.residual_correlation)) continue;
    all.push_back(row.residual_correlation);
    window.add(row.residual_correlation);
    if (window.frames() == kFitWindowFrames) {
      s->residual_correlation_window_max = std::fmax(s->residual_correlation_window_max, window.median());
    }
  }
  if (all.empty()) return;
  const auto mid = all.begin() + static_cast<std::ptrdiff_t>(all.size() / 2);
  std::nth_element(all.begin(), mid, all.end());
  s->residual_correlation_median = *mid;
}

}  // namespace

MethodSummary runMethod(const std::string& method, MethodRunner* runner, const std::vector<FramePair>& pairs) {
  MethodSummary s;
  s.method = method;
  s.backend = runner->backend();
  double true_trans_sum = 0;
  int true_trans_n = 0;
  for (const FramePair& p : pairs) {
    if (std::isfinite(p.true_translation)) {
      true_trans_sum += p.true_translation;
      ++true_trans_n;
    }
    const MethodEstimate e = runner->run(p);
    FrameRow row;
    row.estimate.valid = e.valid;
    row.estimate.rotation = e.rotation;
    row.estimate.dt = p.dt;
    row.estimate.has_covariance = e.has_covariance;
    row.estimate.covariance = e.covariance;
    row.frame = p.index;
    row.matches = static_cast<int>(p.previous.size());
    row.valid = e.valid;
    row.estimate_ms = e.estimate_ms;
    row.inliers = e.inliers;
    row.pure_rotation = e.pure_rotation;
    row.translation = e.translation;
    row.diagnostics = e.diagnostics;
    row.half_resolution = p.half_resolution;
    row.residual_correlation = e.residual_correlation;
    row.error = e.error;
    if (e.has_covariance) {
      row.sigma_deg = std::sqrt(e.covariance.trace()) * kRadToDeg;
      row.sigma_axes_deg = e.covariance.diagonal().cwiseSqrt() * kRadToDeg;
    }
    if (!e.valid && s.first_error.empty()) s.first_error = "frame " + std::to_string(p.index) + ": " + e.error;
    s.detect += p.front_end.detect;
    s.describe += p.front_end.describe;
    s.match += p.front_end.match;
    s.align += p.front_end.align;
    s.estimate += e.estimate_ms;
    s.vote += e.vote_ms;
    s.vote_device += e.vote_device_ms;
    s.refine += e.refine_ms;
    s.matches_mean += row.matches;
    s.tracked_mean += p.tracked;
    if (p.matching == PairMatching::kGuided) ++s.guided_pairs;
    if (p.matching == PairMatching::kGlobalFallback) ++s.fallback_pairs;
    if (p.half_resolution) ++s.half_resolution_pairs;
    s.rows.push_back(row);
  }
  if (!pairs.empty()) {
    const double n = static_cast<double>(pairs.size());
    s.detect /= n;
    s.describe /= n;
    s.match /= n;
    s.align /= n;
    s.estimate /= n;
    s.vote /= n;
    s.vote_device /= n;
    s.refine /= n;
    s.total = s.detect + s.describe + s.match + s.align + s.estimate;
    s.matches_mean /= n;
    s.tracked_mean /= n;
  }
  if (true_trans_n > 0) s.true_translation_mean = true_trans_sum / true_trans_n;
  summarizeCalibrationFit(&s);
  return s;
}

void scoreMethod(const std::vector<FramePair>& pairs, MethodSummary* summary) {
  if (pairs.size() != summary->rows.size())
    throw std::invalid_argument("scoreMethod: " + std::to_string(summary->rows.size()) + " rows for " +
                                std::to_string(pairs.size()) + " pairs");
  metrics::AccuracyAccumulator accuracy;
  for (size_t k = 0; k < pairs.size(); ++k) {
    FrameRow& row = summary->rows[k];
    row.errors = metrics::scoreFrame(row.estimate, pairs[k].truth);
    accuracy.add(row.valid, row.errors, pairs[k].truth);
  }
  summary->accuracy = accuracy.summary();
}

MethodSummary evaluateMethod(const std::string& method, MethodRunner* runner, const std::vector<FramePair>& pairs) {
  MethodSummary s = runMethod(method, runner, pairs);
  scoreMethod(pairs, &s);
  return s;
}

ImuAlignment alignGyroTruth(const Sequence& seq, size_t reference, std::vector<FramePair>* pairs,
                            std::vector<MethodSummary>* summaries) {
  const MethodSummary& by = summaries->at(reference);
  std::vector<VisualRate> rates;
  for (size_t k = 0; k < pairs->size() && k < by.rows.size(); ++k) {
    const FramePair& p = (*pairs)[k];
    const FrameRow& row = by.rows[k];
    VisualRate rate;
    rate.start = seq.stamps[p.previous_index];
    rate.end = seq.stamps[p.index];
    rate.valid = row.valid && p.dt > 0.0;
    if (rate.valid) {
      rate.rate = so3Log(row.estimate.rotation) / p.dt;
      const double pixel = 1.0 / seq.camera.fx();  // [rad]
      rate.covariance = (row.estimate.has_covariance ? row.estimate.covariance
                                                     : Eigen::Matrix3d(pixel * pixel * Eigen::Matrix3d::Identity())) /
                        (p.dt * p.dt);
    }
    rates.push_back(rate);
  }
  ImuAlignmentSettings settings;
  settings.rotation_known = true;
  settings.known_imu_from_camera = seq.body_from_camera;
  const ImuAlignment alignment = alignImu(rates, seq.gyro, settings);
  Sequence aligned = seq;
  aligned.gyro = alignedGyro(seq.gyro, alignment);
  for (FramePair& p : *pairs) fillPairTruth(aligned, &p);
  for (MethodSummary& s : *summaries) scoreMethod(*pairs, &s);
  return alignment;
}

std::string summaryText(const RunDescription& run, const MethodSummary& s) {
  const metrics::AccuracySummary& a = s.accuracy;
  std::ostringstream out;
  out << "== " << s.method << " on " << run.dataset << " (" << run.layout << ", backend " << backendName(s.backend) << ")\n";
  out << "   frames " << a.frames << ", invalid " << a.invalid
      << " (invalid frames count as identity rotation in the errors)";
  if (run.outliers > 0) out << ", injected outliers " << fmt(100.0 * run.outliers, 0) << " %";
  if (run.moving_region > 0)
    out << ", " << fmt(100.0 * run.moving_region, 0) << " % of the matches moving by " << fmt(run.moving_deg, 2) << " deg";
  if (run.stride > 1) out << ", stride " << run.stride;
  if (run.scale != 1.0) out << ", images downscaled by " << fmt(run.scale, 3);
  if (run.degradation.any()) {
    out << ", images degraded (";
    if (run.degradation.gain_jitter > 0) out << "gain 1 +- " << fmt(run.degradation.gain_jitter, 2) << ", ";
    out << "contrast " << fmt(run.degradation.contrast, 2) << ", noise " << fmt(run.degradation.noise_sigma, 1)
        << " grey levels";
    if (run.degradation.stuck_pixels > 0) out << ", " << run.degradation.stuck_pixels << " stuck pixels";
    if (run.degradation.jpeg_quality > 0) out << ", JPEG " << run.degradation.jpeg_quality;
    out << ")";
  }
  out << "\n";
  out << "   rotation error  RMSE " << fmt(a.rot_rmse_deg) << " deg, max " << fmt(a.rot_max_deg) << " deg\n";
  out << "   yaw error       RMSE " << fmt(a.yaw_rmse_deg) << " deg, max " << fmt(a.yaw_max_deg) << " deg\n";
  out << "   rate            mean " << fmt(a.mean_rate_dps) << " deg/s";
  if (std::isfinite(a.rate_rmse_dps) && run.truth == "gyro" && run.gyro_alignment != nullptr) {
    const ImuAlignment& g = *run.gyro_alignment;
    out << ", RMSE vs gyro " << fmt(a.rate_rmse_dps) << " deg/s (gyro aligned: bias " << fmt(g.gyro_bias.x(), 4)
        << " " << fmt(g.gyro_bias.y(), 4) << " " << fmt(g.gyro_bias.z(), 4) << " rad/s removed, offset "
        << (g.offset_observable ? fmt(g.time_offset * 1e3) + " ms" : std::string("not observable (0)"))
        << "; mean |rate| " << fmt(a.true_rate_mean_dps) << " deg/s)";
  } else if (std::isfinite(a.rate_rmse_dps) && run.truth == "gyro") {
    // The raw gyro (bias included): on a static stretch the reference itself reads the bias; its
    // mean is shown to make that visible.
    out << ", RMSE vs gyro " << fmt(a.rate_rmse_dps) << " deg/s (gyro: raw, bias not removed, mean |rate| "
        << fmt(a.true_rate_mean_dps) << " deg/s)";
  } else if (std::isfinite(a.rate_rmse_dps)) {
    out << ", RMSE vs poses " << fmt(a.rate_rmse_dps) << " deg/s (mean |rate| " << fmt(a.true_rate_mean_dps)
        << " deg/s)";
  }
  out << "\n";
  if (std::isfinite(a.nees_mean))
    out << "   covariance      NEES mean " << fmt(a.nees_mean, 2) << " (3 when honest), beyond 99 % bound "
        << fmt(100.0 * a.nees_beyond99, 1) << " % of valid frames\n";
  out << "   matches         mean " << fmt(s.matches_mean, 1) << " (front end " << s.front_end;
  if (s.matching) {
    out << ", matching " << matchingModeName(*s.matching);
    if (*s.matching == MatchingMode::kGuided)
      out << ": " << s.guided_pairs << " pairs guided, " << s.fallback_pairs << " fell back to global";
  }
  if (s.tracked_mean > 0.0) out << "; " << fmt(s.tracked_mean, 1) << " of them tracked";
  if (s.half_resolution_pairs > 0) out << "; " << s.half_resolution_pairs << " pairs at half resolution";
  out << ")\n";
  out << "   ms per frame    detect " << fmt(s.detect) << ", describe " << fmt(s.describe) << ", match "
      << fmt(s.match) << ", align " << fmt(s.align) << ", estimate " << fmt(s.estimate) << ", total " << fmt(s.total) << "\n";
  if (std::isfinite(s.vote)) {
    out << "   estimate split  vote " << fmt(s.vote);
    if (std::isfinite(s.vote_device)) out << " (GPU kernels " << fmt(s.vote_device) << ")";
    out << ", refine " << fmt(s.refine) << "\n";
  }
  if (std::isfinite(s.residual_correlation_median)) {
    out << "   calibration fit residual correlation of neighbouring matches: median "
        << fmt(s.residual_correlation_median, 2) << ", largest " << kFitWindowFrames << "-frame median "
        << fmt(s.residual_correlation_window_max, 2) << " (covariance inflated from "
        << fmt(kFitMismatchCorrelation, 2) << ")\n";
  }
  if (!s.first_error.empty()) out << "   first invalid   " << s.first_error << "\n";
  return out.str();
}

std::string summaryJson(const RunDescription& run, const MethodSummary& s) {
  const metrics::AccuracySummary& a = s.accuracy;
  JsonObject times;
  times.add("detect", s.detect).add("describe", s.describe).add("match", s.match).add("align", s.align)
      .add("estimate", s.estimate).add("total", s.total);
  if (std::isfinite(s.vote)) times.add("vote", s.vote).add("vote_device", s.vote_device).add("refine", s.refine);
  JsonObject j;
  j.add("dataset", run.dataset).add("method", s.method);
  metrics::addAccuracyFields(a, &j);
  j.add("ms_per_frame", times)
      .add("backend", backendName(s.backend))
      .add("matches_mean", s.matches_mean)
      .add("tracked_mean", s.tracked_mean)
      .add("front_end", s.front_end)
      .add("matching", s.matching ? matchingModeName(*s.matching) : "")
      .add("guided_pairs", s.guided_pairs)
      .add("fallback_pairs", s.fallback_pairs)
      .add("half_resolution_pairs", s.half_resolution_pairs)
      .add("layout", run.layout)
      .add("hypotheses", isOwnMethod(s.method) ? run.hypotheses : 0)
      .add("outliers", run.outliers)
      .add("moving_region", run.moving_region)
      .add("moving_deg", run.moving_deg)
      .add("stride", run.stride)
      .add("gain_jitter", run.degradation.gain_jitter)
      .add("contrast", run.degradation.contrast)
      .add("noise", run.degradation.noise_sigma)
      .add("stuck_pixels", run.degradation.stuck_pixels)
      .add("jpeg", run.degradation.jpeg_quality)
      .add("scale", run.scale)
      .add("true_rot_mean_deg", a.true_rotation_mean_deg)
      .add("true_trans_mean_m", s.true_translation_mean)
      .add("gyro_mean_rate_dps", a.true_rate_mean_dps)
      .add("truth", run.truth);
  addAlignmentSummary(run.gyro_alignment, &j);
  j.add("gyro_aligned", run.gyro_alignment != nullptr)
      .add("nees_mean", a.nees_mean)
      .add("nees_beyond_99", a.nees_beyond99);
  return j.str();
}

void writeFrameCsv(const std::string& path, const std::vector<MethodSummary>& all) {
  std::ofstream f(path);
  if (!f) throw DataError("cannot write " + path);
  f << "frame,method,matches,valid,yaw_est_deg,yaw_true_deg,rot_err_deg,yaw_err_deg,rate_dps,estimate_ms,"
       "rate_err_dps,nees,sigma_deg,inliers,pure_rotation,prior_used,wide_vote,winner_source,candidates,"
       "rotation_inliers,epipolar_inliers,runner_up_inliers,valley,prior_offset_deg,residual_sigma_deg,effective_matches,near_miss_share,refit_jackknife,descriptor_areas,half_resolution,err_x_deg,err_y_deg,"
       "err_z_deg,sigma_x_deg,sigma_y_deg,sigma_z_deg,t_x,t_y,t_z,residual_correlation,row_skew_deg,error\n";
  auto num = [](double v) -> std::string {
    if (!std::isfinite(v)) return "";
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.6g", v);
    return buf;
  };
  for (const MethodSummary& s : all) {
    for (const FrameRow& r : s.rows) {
      const metrics::FrameErrors& e = r.errors;
      f << r.frame << ',' << s.method << ',' << r.matches << ',' << (r.valid ? 1 : 0) << ',' << num(e.yaw_deg)
        << ',' << num(e.true_yaw_deg) << ',' << num(e.rotation_error_deg) << ',' << num(e.yaw_error_deg) << ','
        << num(e.rate_dps) << ',' << num(r.estimate_ms) << ',' << num(e.rate_error_dps) << ',' << num(e.nees)
        << ',' << num(r.sigma_deg) << ',' << r.inliers << ',' << (r.pure_rotation ? 1 : 0) << ','
        << (r.diagnostics.prior_used ? 1 : 0) << ',' << (r.diagnostics.wide_vote ? 1 : 0) << ','
        << r.diagnostics.winner_source << ',' << r.diagnostics.candidates_verified << ','
        << r.diagnostics.rotation_inliers << ',' << r.diagnostics.epipolar_inliers << ','
        << r.diagnostics.runner_up_inliers << ','
        << (r.diagnostics.valley_moved ? "moved" : r.diagnostics.valley_searched ? "searched" : "") << ','
        << num(r.diagnostics.prior_offset * kRadToDeg) << ',' << num(r.diagnostics.residual_sigma * kRadToDeg) << ','
        << num(r.diagnostics.effective_matches) << ',' << num(r.diagnostics.near_miss_share) << ','
        << (r.diagnostics.refit_jackknife ? 1 : 0) << ',' << num(r.diagnostics.descriptor_areas) << ','
        << (r.half_resolution ? 1 : 0);
      for (int k = 0; k < 3; ++k) f << ',' << num(e.error_vector_deg[k]);
      for (int k = 0; k < 3; ++k) f << ',' << num(r.sigma_axes_deg[k]);
      for (int k = 0; k < 3; ++k) f << ',' << num(r.translation[k]);
      f << ',' << num(r.residual_correlation) << ',' << num(r.diagnostics.row_skew.norm() * kRadToDeg);
      f << ",\"" << r.error << "\"\n";
    }
  }
  if (!f) throw DataError("cannot write " + path);
}

}  // namespace eval
}  // namespace visual_gyro
