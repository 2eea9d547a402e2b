#include "method_runners.h"

#include <algorithm>
#include <chrono>
#include <iostream>

#include "visual_gyro/calibration_fit.h"
#include "visual_gyro/geometry.h"

namespace visual_gyro {
namespace eval {
namespace {

double elapsedMs(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

/// vote / paper: a RotationEstimator fed the prior VisualGyro would give it (its own previous
/// valid rotation vector, rescaled to this interval; none after an invalid estimate).
class OwnEstimatorRunner : public MethodRunner {
 public:
  OwnEstimatorRunner(const EstimatorSettings& settings, const VisualGyroSettings& pipeline, bool refined_positions,
                     double match_footprint, uint32_t disabled_parts)
      : estimator_(createRotationEstimator(settings, [](const std::string& w) {
          std::cerr << "warning: " << w << "\n";
        })),
        backend_(estimator_->backend()),
        pipeline_(pipeline) {
    estimator_->setDisabledParts(disabled_parts);
    estimator_->setRefinedPositions(refined_positions);
    estimator_->setMatchFootprint(match_footprint);
  }

  MethodEstimate run(const FramePair& pair) override {
    const RotationPrior prior = prior_.priorFor(pair.dt);
    const auto start = std::chrono::steady_clock::now();
    const RotationResult r = estimator_->estimate(pair.previous, pair.current, prior);
    MethodEstimate out;
    out.estimate_ms = elapsedMs(start);
    out.vote_ms = r.times.vote;
    out.vote_device_ms = backend_ == Backend::kCuda ? r.times.vote_device : std::numeric_limits<double>::quiet_NaN();
    out.refine_ms = r.times.refine;
    // As in VisualGyro, an implausible rate is no prior for the next pair (PlausibilityRunner
    // reports it).
    const bool implausible = r.valid() && !checkRatePlausible(r.rotation_vector, pair.dt, pipeline_).empty();
    prior_.update(implausible ? RotationResult() : r, pair.dt);
    out.valid = r.valid();
    out.status = r.status;
    if (!out.valid) out.error = std::string(frameStatusName(r.status)) + ": " + r.reason;
    out.inliers = r.inliers;
    out.pure_rotation = r.pure_rotation;
    out.translation = r.translation;
    out.diagnostics = r.diagnostics;
    if (out.valid) {
      out.rotation = r.rotation;
      out.rotation_vector = r.rotation_vector;
      out.has_covariance = true;
      out.covariance = r.covariance;
    }
    return out;
  }
  Backend backend() const override { return backend_; }

 private:
  std::unique_ptr<RotationEstimator> estimator_;
  Backend backend_;  // estimator_'s voter, fixed at its creation
  VisualGyroSettings pipeline_;  // its max_rate_dps
  PriorTracker prior_;  // the same prior VisualGyro gives its estimator
};

/// OpenCV / OpenGV baselines; the eigensolver starts from this method's previous valid estimate.
class BaselineRunner : public MethodRunner {
 public:
  BaselineRunner(const std::string& name, const BaselineSettings& settings) : name_(name), settings_(settings) {}

  MethodEstimate run(const FramePair& pair) override {
    BaselineSettings s = settings_;
    s.seed = settings_.seed + pair.index;
    const auto start = std::chrono::steady_clock::now();
    const BaselineResult r = runBaseline(name_, pair.previous, pair.current, s, initial_);
    MethodEstimate out;
    out.estimate_ms = elapsedMs(start);
    out.valid = r.valid;
    out.status = r.status;
    out.error = r.error;
    if (r.valid) {
      out.rotation = r.rotation;
      out.rotation_vector = so3Log(r.rotation);
      initial_ = r.rotation;
    } else {
      initial_.setIdentity();
    }
    return out;
  }
  Backend backend() const override { return Backend::kCpu; }

 private:
  std::string name_;
  BaselineSettings settings_;
  Eigen::Matrix3d initial_ = Eigen::Matrix3d::Identity();
};

/// Applies the pipeline's plausibility rules to a method: no estimate on a frozen or textureless
/// image, a rate above max_rate_dps is invalid and, when `judge_calibration` (vote), every
/// estimate's covariance is inflated while the calibration does not fit, exactly as VisualGyro
/// reports them.
class PlausibilityRunner : public MethodRunner {
 public:
  PlausibilityRunner(std::unique_ptr<MethodRunner> inner, const VisualGyroSettings& settings,
                     bool judge_calibration, double pixel_angle_rad)
      : inner_(std::move(inner)),
        settings_(settings),
        judge_calibration_(judge_calibration),
        pixel_angle_rad_(pixel_angle_rad) {}

  MethodEstimate run(const FramePair& pair) override {
    if (pair.image_status != FrameStatus::kValid) {
      MethodEstimate out;
      out.status = pair.image_status;
      out.error = pair.unusable_image;
      return out;
    }
    MethodEstimate out = inner_->run(pair);
    if (out.valid) {
      const std::string implausible = checkRatePlausible(out.rotation_vector, pair.dt, settings_);
      if (!implausible.empty()) {
        out.valid = false;
        out.status = FrameStatus::kImplausibleRate;
        out.error = std::string(frameStatusName(out.status)) + ": " + implausible;
        out.rotation.setIdentity();
        out.rotation_vector.setZero();
      }
    }
    if (out.valid && judge_calibration_) judgeCalibration(pair, &out);
    return out;
  }
  Backend backend() const override { return inner_->backend(); }

 private:
  /// VisualGyro::checkCalibrationFit on the pair's bearings.
  void judgeCalibration(const FramePair& pair, MethodEstimate* out) {
    out->residual_correlation =
        correlation_.compute(pair.previous, pair.current, out->rotation, out->translation, pixel_angle_rad_,
                             settings_.estimator.inlier_threshold_deg * kDegToRad, out->diagnostics.row_skew);
    fit_.add(out->residual_correlation);
    if (out->has_covariance) out->covariance *= fit_.covarianceInflation();
  }

  std::unique_ptr<MethodRunner> inner_;
  VisualGyroSettings settings_;
  bool judge_calibration_ = false;
  double pixel_angle_rad_ = 0.0;
  ResidualCorrelation correlation_;
  CalibrationFitMonitor fit_;
};

constexpr const char* kAblationPrefix = "vote-without-";

// vote-without-<part>[+<part>...]: true with the parts' mask (bit k: VotePart k off) when
// `method` names one or more parts.
bool parseAblation(const std::string& method, uint32_t* disabled) {
  const std::string prefix(kAblationPrefix);
  if (method.compare(0, prefix.size(), prefix) != 0) return false;
  *disabled = 0;
  size_t begin = prefix.size();
  while (begin <= method.size()) {
    const size_t end = std::min(method.find('+', begin), method.size());
    VotePart part;
    if (!parseVotePart(method.substr(begin, end - begin), &part)) return false;
    *disabled |= 1u << static_cast<int>(part);
    begin = end + 1;
  }
  return true;
}

}  // namespace

bool isOwnMethod(const std::string& method) {
  EstimationMethod parsed;
  uint32_t disabled;
  return parseMethod(method, &parsed) || parseAblation(method, &disabled);
}

std::vector<std::string> ablationMethodNames() {
  std::vector<std::string> names;
  for (int k = 0; k < static_cast<int>(VotePart::kCount); ++k)
    names.push_back(kAblationPrefix + std::string(votePartName(static_cast<VotePart>(k))));
  return names;
}

std::vector<std::string> methodNames() {
  std::vector<std::string> names{methodName(EstimationMethod::kVote), methodName(EstimationMethod::kPaper)};
  for (const auto& n : baselineNames())
    if (isBaselineCompiled(n)) names.push_back(n);
  return names;
}

std::string methodProblem(const std::string& method) {
  if (isOwnMethod(method) || isBaselineCompiled(method)) return "";
  if (isOpenGvBaseline(method)) {
    return "method '" + method + "' needs OpenGV, which this build does not have (install libopengv-dev and rebuild)";
  }
  std::string known = "vote, paper, vote-without-<part>[+<part>...] (evaluate --list-ablations)";
  for (const auto& n : baselineNames()) known += ", " + n;
  return "unknown method '" + method + "' (known: " + known + ")";
}

std::unique_ptr<MethodRunner> makeRunner(const std::string& method, const VisualGyroSettings& settings,
                                         const BaselineSettings& baseline, bool refined_positions,
                                         double match_footprint, double pixel_angle_rad) {
  std::unique_ptr<MethodRunner> runner;
  EstimatorSettings estimator = settings.estimator;
  uint32_t disabled = 0;
  const bool ablation = parseAblation(method, &disabled);
  if (ablation) estimator.method = EstimationMethod::kVote;
  const bool own = ablation || parseMethod(method, &estimator.method);
  if (own) {
    runner = std::make_unique<OwnEstimatorRunner>(estimator, settings, refined_positions, match_footprint, disabled);
  } else {
    runner = std::make_unique<BaselineRunner>(method, baseline);
  }
  // VisualGyro judges the calibration from the vote method's estimates only.
  const bool judge = own && estimator.method == EstimationMethod::kVote;
  return std::make_unique<PlausibilityRunner>(std::move(runner), settings, judge, pixel_angle_rad);
}

}  // namespace eval
}  // namespace visual_gyro
