#include "frame_pairs.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>

#include <unistd.h>

#include <opencv2/imgcodecs.hpp>

#include "bearing_file.h"
#include "comparison_front_ends.h"
#include "visual_gyro/geometry.h"
#include "visual_gyro/random.h"

namespace visual_gyro {
namespace eval {

void fillPairTruth(const Sequence& seq, FramePair* p) {
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  bool ok = true;
  for (size_t k = p->previous_index + 1; k <= p->index && ok; ++k) {
    Eigen::Matrix3d step;
    ok = seq.trueRotation(k, &step);
    if (ok) r = r * step;
  }
  p->truth.has_rotation = ok;
  p->truth.from_poses = ok && seq.hasPoses();
  // Each composed frame-to-frame step brings its own truth error.
  if (p->truth.from_poses) {
    p->truth.sigma_rad =
        seq.truth_sigma_deg * (kDegToRad * std::sqrt(static_cast<double>(p->index - p->previous_index)));
  }
  if (ok) p->truth.rotation = r;
  if (seq.positions.size() == seq.image_paths.size()) {
    p->true_translation = (seq.positions[p->index] - seq.positions[p->previous_index]).norm();
  }
  // A rate reference where one was measured independently of the frame steps: the gyro, or
  // EuRoC's ground-truth poses (KITTI's poses already give the rotation errors).
  if (seq.truth == "gyro" || seq.truth == "poses") {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double weight = 0.0;
    bool gyro_ok = true;
    for (size_t k = p->previous_index + 1; k <= p->index && gyro_ok; ++k) {
      Eigen::Vector3d w;
      gyro_ok = seq.trueAngularVelocity(k, &w);
      const double dt = seq.stamps[k] - seq.stamps[k - 1];
      sum += w * dt;
      weight += dt;
    }
    p->truth.has_rate = gyro_ok && weight > 0.0;
    if (p->truth.has_rate) p->truth.rate = sum / weight;
  }
}

namespace {

/// 0..n-1 in a deterministic random order.
std::vector<size_t> shuffledIndices(size_t n, SplitMix64* rng) {
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  rng->shuffle(order);
  return order;
}

/// Replaces the fraction `fraction` of the matches by wrong pairings: the current-frame bearing of
/// a chosen match becomes that of another, distant match (>= ~20 px away at `angle_per_px`), so
/// every replaced match is a real feature paired with the wrong partner. Deterministic in seed.
void injectOutliers(double fraction, uint64_t seed, double angle_per_px, FramePair* p) {
  const size_t n = p->previous.size();
  const size_t count = static_cast<size_t>(std::llround(fraction * static_cast<double>(n)));
  if (count == 0 || n < 2) return;
  SplitMix64 rng(seed * 0xD1B54A32D192ED03ull + 0x5bd1e995ull + p->index);
  const std::vector<size_t> order = shuffledIndices(n, &rng);
  const std::vector<Eigen::Vector3d> original = p->current;
  const double min_cos = std::cos(20.0 * angle_per_px);
  for (size_t c = 0; c < count; ++c) {
    const size_t i = order[c];
    size_t j = rng.below(n);
    for (int attempt = 0; attempt < 20 && (j == i || original[i].dot(original[j]) > min_cos); ++attempt) {
      j = rng.below(n);
    }
    if (j == i) j = (i + 1) % n;
    p->current[i] = original[j];
  }
}

}  // namespace

void moveRegion(double fraction, double angle_deg, FramePair* p) {
  const size_t n = p->previous.size();
  const size_t count = static_cast<size_t>(std::llround(fraction * static_cast<double>(n)));
  if (count == 0) return;
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  // Ties broken by index, so that the region is the same with every standard library.
  const auto rightward = [&](size_t a, size_t b) {
    const double xa = std::atan2(p->previous[a].x(), p->previous[a].z());
    const double xb = std::atan2(p->previous[b].x(), p->previous[b].z());
    return xa != xb ? xa > xb : a < b;
  };
  std::sort(order.begin(), order.end(), rightward);
  const Eigen::Matrix3d turn = so3Exp(angle_deg * kDegToRad * Eigen::Vector3d::UnitY());
  for (size_t c = 0; c < count; ++c) p->current[order[c]] = turn * p->current[order[c]];
}

void subsampleMatches(int max_matches, uint64_t seed, FramePair* p) {
  const size_t n = p->previous.size();
  if (max_matches <= 0 || n <= static_cast<size_t>(max_matches)) return;
  SplitMix64 rng(seed * 0x9E3779B97F4A7C15ull + p->index);
  std::vector<size_t> order = shuffledIndices(n, &rng);
  order.resize(max_matches);
  std::sort(order.begin(), order.end());
  std::vector<Eigen::Vector3d> a, b;
  for (size_t i : order) {
    a.push_back(p->previous[i]);
    b.push_back(p->current[i]);
  }
  p->previous.swap(a);
  p->current.swap(b);
}

namespace {

/// Image k of the sequence as the front end sees it: read (DataError when it cannot be), then
/// degraded as the options say.
cv::Mat readPairImage(const Sequence& seq, size_t k, const FramePairOptions& o) {
  cv::Mat gray;
  try {
    gray = readImage(seq, k);
  } catch (const std::exception& e) {
    throw DataError(e.what());
  }
  // Degraded at the resolution the front end sees, as a camera of that resolution would be.
  if (o.degradation.any()) gray = degradeImage(gray, o.degradation, o.seed * 0x9E3779B97F4A7C15ull + k);
  return gray;
}

/// Image k (`gray`) through the comparison front end `other`: when it paired the image with the
/// previous one (image previous_index), the pairs' bearings, dt and stage times.
/// `previous_pixels` and `current_pixels` are working space. DataError for an image that is not
/// the camera's size.
FrameResult comparisonFrame(ComparisonFrontEnd* other, const Sequence& seq, size_t k, size_t previous_index, const cv::Mat& gray, std::vector<cv::Point2f>* previous_pixels,
                            std::vector<cv::Point2f>* current_pixels) {
  FrameResult r;
  if (gray.cols != seq.camera.width() || gray.rows != seq.camera.height()) {
    throw DataError("image " + seq.image_paths[k] + " is " + std::to_string(gray.cols) + "x" +
                    std::to_string(gray.rows) + " but the camera model is " +
                    std::to_string(seq.camera.width()) + "x" + std::to_string(seq.camera.height()));
  }
  const bool paired = other->process(gray, previous_pixels, current_pixels, &r.times);
  if (paired) {
    r.dt = seq.stamps[k] - seq.stamps[previous_index];
    for (size_t i = 0; i < previous_pixels->size(); ++i) {
      r.previous_bearings.push_back(seq.camera.bearing((*previous_pixels)[i].x, (*previous_pixels)[i].y));
      r.current_bearings.push_back(seq.camera.bearing((*current_pixels)[i].x, (*current_pixels)[i].y));
    }
  }
  return r;
}

/// The pair (previous_index, k) from the front end's result `r` (its bearings are moved out),
/// with its truth, subsampled, with outliers injected and a region moved as the options say.
/// `unusable`: the image left the previous one in place (frozen or textureless).
FramePair makePair(const Sequence& seq, size_t previous_index, size_t k, bool unusable, const FramePairOptions& o,
                   FrameResult* r) {
  FramePair p;
  p.previous_index = previous_index;
  p.index = k;
  p.dt = r->dt > 0.0 ? r->dt : seq.stamps[k] - seq.stamps[previous_index];
  p.previous = std::move(r->previous_bearings);
  p.current = std::move(r->current_bearings);
  p.front_end = r->times;
  if (unusable) {
    p.image_status = r->status;
    p.unusable_image = std::string(frameStatusName(r->status)) + ": " + r->reason;
  }
  p.matching = r->matching;
  p.tracked = r->tracked;
  p.half_resolution = r->half_resolution;
  fillPairTruth(seq, &p);
  subsampleMatches(o.max_matches, o.seed, &p);
  injectOutliers(o.outliers, o.seed, 1.0 / seq.camera.fx(), &p);
  moveRegion(o.moving_region, o.moving_deg, &p);
  return p;
}

/// Reports the frames skipped for a time step below min_dt (DataError when no pair is left) and,
/// unless quiet, the pair count.
void reportPairs(const Sequence& seq, const VisualGyroSettings& settings, const FramePairOptions& o,
                 const std::vector<FramePair>& pairs, size_t skipped_min_dt, const std::string& first_skip) {
  if (skipped_min_dt > 0) {
    std::fprintf(stderr, "[evaluate] %s: %zu frame(s) skipped, time step below min_dt %g s (first: %s)\n",
                 seq.name.c_str(), skipped_min_dt, settings.min_dt, first_skip.c_str());
    if (pairs.empty()) {
      throw DataError(seq.name + ": no usable frame pairs: every time step is below min_dt (" +
                      std::to_string(skipped_min_dt) + " frames skipped; first: " + first_skip + ")");
    }
  }
  if (!o.quiet && !pairs.empty()) {
    double matches = 0;
    for (const FramePair& p : pairs) matches += p.previous.size();
    std::fprintf(stderr, "[evaluate] %s: %zu frame pairs, %.1f matches per pair\n", seq.name.c_str(), pairs.size(),
                 matches / pairs.size());
  }
}

}  // namespace

std::vector<FramePair> collectFramePairs(const Sequence& seq, const VisualGyroSettings& settings,
                                         const FramePairOptions& o) {
  VisualGyroSettings front_end_only = settings;
  front_end_only.estimator.backend = BackendChoice::kCpu;
  front_end_only.estimator.method = EstimationMethod::kVote;
  front_end_only.run_estimator = settings.front_end.matching == MatchingMode::kGuided;
  VisualGyro gyro(seq.camera, front_end_only, [](const std::string& w) { std::cerr << "warning: " << w << "\n"; });
  std::unique_ptr<ComparisonFrontEnd> other;
  if (o.front_end != "native") other = makeComparisonFrontEnd(o.front_end);
  std::vector<cv::Point2f> previous_pixels, current_pixels;
  std::vector<FramePair> pairs;
  bool have_previous = false;
  size_t previous_index = 0;
  size_t skipped_min_dt = 0;
  std::string first_skip;
  // A live counter only on a terminal; logs get one line at the end.
  const bool progress = !o.quiet && isatty(fileno(stderr));
  for (size_t k = 0; k < seq.image_paths.size(); k += o.stride) {
    if (o.frames > 0 && static_cast<long long>(pairs.size()) >= o.frames) break;
    const cv::Mat gray = readPairImage(seq, k, o);
    FrameResult r;
    if (other) {
      r = comparisonFrame(other.get(), seq, k, previous_index, gray, &previous_pixels, &current_pixels);
    } else {
      r = gyro.processFrame(gray, seq.stamps[k]);
      if (r.status == FrameStatus::kTimeStepTooSmall) {
        // The pipeline skipped the frame; the next pairs with the previous.
        if (skipped_min_dt++ == 0) first_skip = "image " + seq.image_paths[k] + ": " + r.reason;
        continue;
      }
      // Image-level problems (size mismatch, bad stamp) are data errors; a frozen frame and the
      // front-end pipeline's own estimate (guided matching) failing are not.
      if (r.skipped()) throw DataError("image " + seq.image_paths[k] + ": " + r.reason);
    }
    // A frozen or textureless image leaves the pipeline's previous frame in place; so does this
    // loop (before the first usable image there is none).
    const bool unusable = r.status == FrameStatus::kFrozenImage || r.status == FrameStatus::kNoTexture;
    if (!have_previous) {
      if (unusable) continue;
      have_previous = true;
      previous_index = k;
      continue;
    }
    FramePair p = makePair(seq, previous_index, k, unusable, o, &r);
    if (progress) {
      std::fprintf(stderr, "\r[evaluate] front end: pair %zu (images %zu-%zu), %zu matches   ",
                   pairs.size() + 1, previous_index, k, p.previous.size());
    }
    pairs.push_back(std::move(p));
    if (!unusable) previous_index = k;
  }
  if (progress) std::fprintf(stderr, "\n");
  reportPairs(seq, settings, o, pairs, skipped_min_dt, first_skip);
  return pairs;
}

void exportBearings(const std::vector<FramePair>& pairs, const std::string& path) {
  std::vector<bearings::BearingFrame> frames(pairs.size());
  for (size_t k = 0; k < pairs.size(); ++k) {
    const FramePair& p = pairs[k];
    bearings::BearingFrame& f = frames[k];
    f.index = static_cast<int64_t>(p.index);
    f.dt = p.dt;
    f.has_truth = p.truth.has_rotation;
    if (f.has_truth)
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) f.truth[3 * r + c] = p.truth.rotation(r, c);
    auto toFloat = [](const Eigen::Vector3d& v) {
      return hyp::make3(static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z()));
    };
    for (size_t i = 0; i < p.previous.size(); ++i) {
      f.prev.push_back(toFloat(p.previous[i]));
      f.cur.push_back(toFloat(p.current[i]));
    }
  }
  try {
    bearings::writeBearingFile(path, frames);
  } catch (const std::runtime_error& e) {
    throw DataError(e.what());
  }
}

}  // namespace eval
}  // namespace visual_gyro
