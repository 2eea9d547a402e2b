// libFuzzer target: the whole pipeline (VisualGyro::processFrame: front end, matching, sub-pixel
// alignment, estimator on the CPU voter) on short streams whose images, stamps, camera and
// settings come from the fuzzer. Images are small (16-320 px wide, 16-240 px high, some smaller
// than the pipeline accepts), either raw bytes or a texture shifted between frames with pixels
// overwritten, so that corners match and every stage runs. Up to four settings take fuzzed values
// through applySetting (refused ones are ignored). No input may crash, hang or raise a sanitizer
// report; a frame with an estimate must have a finite proper rotation, a finite rate and exactly
// symmetric, positive semi-definite covariances; a frame without one must say why.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>
#include <opencv2/core.hpp>

#include "visual_gyro/camera_model.h"
#include "visual_gyro/visual_gyro.h"
#include "fuzz_input.h"

namespace vg = visual_gyro;
using namespace vg::fuzz;  // the targets' input reader and checks

namespace {

void checkFrame(const vg::FrameResult& r) {
  if (!r.hasEstimate()) {
    check(r.status == vg::FrameStatus::kFirstFrame || !r.reason.empty(), "a frame without estimate or reason");
    return;
  }
  checkRotation(r.rotation.rotation);
  check(r.angular_velocity.allFinite(), "a non-finite rate");
  checkCovariance(r.rotation.covariance);
  checkCovariance(r.angular_velocity_covariance);
}

// Up to four settings from the input, each by its index in the table and a value: a number, a
// bool or one of the choices' words. Refused values leave the settings as they were.
void fuzzSettings(Bytes& in, vg::VisualGyroSettings* settings) {
  static const char* const kWords[] = {"true", "false", "guided", "global", "vote", "paper", "cpu", "auto"};
  const auto& fields = vg::visualGyroSettingFields();
  const int count = in.byte() % 5;
  for (int k = 0; k < count; ++k) {
    const auto& field = fields[in.byte() % fields.size()];
    const uint8_t kind = in.byte();
    char value[64];
    if (kind < 128) std::snprintf(value, sizeof(value), "%.9g", in.number());
    else std::snprintf(value, sizeof(value), "%s", kWords[kind % (sizeof(kWords) / sizeof(kWords[0]))]);
    vg::applySetting(settings, field.name, value);
  }
  settings->estimator.backend = vg::BackendChoice::kCpu;
  // Every count the table accepts is a valid input, but the largest are too slow for a fuzzer's
  // run (ten million triples a frame): they are capped, not refused.
  settings->estimator.hypotheses = std::min(settings->estimator.hypotheses, 2000);
}

// A frame: raw bytes, or a random texture of bright dots (seeded from the input) shifted by the
// input's offset, with some of its pixels overwritten.
cv::Mat frame(Bytes& in, int width, int height, bool textured, uint32_t texture_seed) {
  cv::Mat image(height, width, CV_8UC1);
  if (!textured) {
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x) image.at<uint8_t>(y, x) = in.byte();
    return image;
  }
  const int dx = in.byte() % 9 - 4, dy = in.byte() % 9 - 4;
  std::mt19937 rng(texture_seed);
  cv::Mat texture(height + 8, width + 8, CV_8UC1);
  for (int y = 0; y < texture.rows; ++y)
    for (int x = 0; x < texture.cols; ++x) texture.at<uint8_t>(y, x) = static_cast<uint8_t>(rng() % 4 == 0 ? 230 : 30);
  texture(cv::Rect(4 + dx, 4 + dy, width, height)).copyTo(image);
  const int edits = in.byte();
  for (int k = 0; k < edits; ++k) image.at<uint8_t>(in.byte() % height, in.byte() % width) = in.byte();
  return image;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Bytes in(data, size);
  const uint8_t options = in.byte();
  const int width = 16 + in.byte() % 305, height = 16 + in.byte() % 225;
  const double focal = 10.0 + in.byte() * 2.0;
  vg::VisualGyroSettings settings;
  fuzzSettings(in, &settings);
  std::unique_ptr<vg::VisualGyro> gyro;
  try {
    gyro = std::make_unique<vg::VisualGyro>(
        vg::CameraModel(focal, focal, 0.5 * (width - 1), 0.5 * (height - 1), width, height), settings);
  } catch (const std::invalid_argument&) {
    return 0;  // an unusable camera or settings: refused with a message, as documented
  }
  const uint32_t texture_seed = in.byte();
  double stamp = 1.0;
  for (int k = 0; k < 4 && !in.done(); ++k) {
    const cv::Mat image = frame(in, width, height, (options & 1) != 0, texture_seed);
    // Mostly 30 Hz; sometimes a stamp from the input (zero, backwards, huge or not finite).
    const uint8_t step = in.byte();
    stamp = step < 200 ? stamp + 1.0 / 30.0 : static_cast<double>(in.number());
    const vg::FrameResult result = gyro->processFrame(image, stamp);
    // FUZZ_VERBOSE=1 prints each frame's outcome (to see what a corpus input reaches).
    static const bool verbose = std::getenv("FUZZ_VERBOSE") != nullptr;
    if (verbose)
      std::fprintf(stderr, "frame %d %dx%d: %s, %zu matches%s%s\n", k, width, height,
                   vg::frameStatusName(result.status), result.previous_bearings.size(),
                   result.reason.empty() ? "" : ": ", result.reason.c_str());
    checkFrame(result);
  }
  return 0;
}
