// render_sequence: renders a synthetic sequence with known motion and writes it in the KITTI
// odometry layout (image_l/*.png, calib.txt, poses.txt, times.txt).
#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <stdexcept>
#include <string>

#include "visual_gyro/renderer.h"

namespace {

const char* const kUsage =
    "usage: render_sequence --preset drive|handheld|forward|dim|drone_near --out DIR [options]\n"
    "  --out DIR       output folder (KITTI layout; --output is accepted too)\n"
    "  --frames N      number of frames (default 60)\n"
    "  --width W       image width [px] (default 640)\n"
    "  --height H      image height [px] (default 480)\n"
    "  --focal F       focal length fx = fy [px] (default 500); the principal point is the centre\n"
    "  --rate HZ       frame rate (default 10 for drive/forward, 30 for handheld/dim, 20 for drone_near)\n"
    "  --noise SIGMA   Gaussian pixel noise [grey levels] (default 2)\n"
    "  --seed S        texture and noise seed (default 7)\n"
    "  --contrast F    scale grey levels about the image mean by F (default 1)\n"
    "  --blur PX       motion blur of PX pixels along the image motion (default 0)\n"
    "  --jpeg Q        JPEG-compress every image at quality Q, 1..100 (default: none)\n"
    "Presets: drive = car at 10 m/s with a right and a left turn (up to 30 deg/s); handheld =\n"
    "rotation about all axes (up to ~40 deg/s) in a room, mm jitter; forward = straight drive;\n"
    "dim = the handheld motion in a dim room of plain walls, doors and boxes (30 grey levels).\n"
    "Poses are camera -> first camera (x right, y down, z forward), positions in metres.\n";

bool parseInt(const std::string& text, long lo, long hi, long* value) {
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || errno != 0 || v < lo || v > hi) return false;
  *value = v;
  return true;
}

bool parseDouble(const std::string& text, double* value) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

int usageError(const std::string& message) {
  std::cerr << "render_sequence: " << message << "\n" << kUsage;
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  visual_gyro::RenderSettings settings;
  std::string out;
  bool preset_given = false, rate_given = false;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg == "--help" || arg == "-h") {
      std::cout << kUsage;
      return 0;
    }
    if (a + 1 >= argc) return usageError("missing value for " + arg);
    const std::string value = argv[++a];
    long n = 0;
    double x = 0;
    if (arg == "--preset") {
      settings.preset = value;
      preset_given = true;
    } else if (arg == "--out" || arg == "--output") {
      out = value;
    } else if (arg == "--frames") {
      if (!parseInt(value, 1, 1000000, &n)) return usageError("bad --frames '" + value + "'");
      settings.frames = static_cast<int>(n);
    } else if (arg == "--width") {
      if (!parseInt(value, 8, 16384, &n)) return usageError("bad --width '" + value + "'");
      settings.width = static_cast<int>(n);
    } else if (arg == "--height") {
      if (!parseInt(value, 8, 16384, &n)) return usageError("bad --height '" + value + "'");
      settings.height = static_cast<int>(n);
    } else if (arg == "--focal") {
      if (!parseDouble(value, &x) || x <= 0) return usageError("bad --focal '" + value + "'");
      settings.fx = settings.fy = x;
    } else if (arg == "--rate") {
      if (!parseDouble(value, &x) || x <= 0) return usageError("bad --rate '" + value + "'");
      settings.rate_hz = x;
      rate_given = true;
    } else if (arg == "--noise") {
      if (!parseDouble(value, &x) || x < 0) return usageError("bad --noise '" + value + "'");
      settings.noise_sigma = x;
    } else if (arg == "--contrast") {
      if (!parseDouble(value, &x) || x <= 0 || x > 100) return usageError("bad --contrast '" + value + "'");
      settings.contrast = x;
    } else if (arg == "--blur") {
      if (!parseDouble(value, &x) || x < 0 || x > 200) return usageError("bad --blur '" + value + "'");
      settings.blur_px = x;
    } else if (arg == "--jpeg") {
      if (!parseInt(value, 1, 100, &n)) return usageError("bad --jpeg '" + value + "' (1..100)");
      settings.jpeg_quality = static_cast<int>(n);
    } else if (arg == "--seed") {
      char* end = nullptr;
      errno = 0;
      const unsigned long long s = std::strtoull(value.c_str(), &end, 10);
      if (value.empty() || value[0] == '-' || *end != '\0' || errno != 0) return usageError("bad --seed '" + value + "'");
      settings.seed = s;
    } else {
      return usageError("unknown argument '" + arg + "'");
    }
  }
  if (!preset_given) return usageError("--preset is required");
  if (settings.preset != "drive" && settings.preset != "handheld" && settings.preset != "forward" &&
      settings.preset != "dim" && settings.preset != "drone_near")
    return usageError("unknown preset '" + settings.preset + "'");
  if (out.empty()) return usageError("--out is required");
  if (!rate_given)
    settings.rate_hz = settings.preset == "handheld" || settings.preset == "dim" ? 30.0
                       : settings.preset == "drone_near"                          ? 20.0
                                                                                  : 10.0;
  settings.setCentredCamera(settings.width, settings.height, settings.fx);

  visual_gyro::RenderedSequence sequence;
  const auto start = std::chrono::steady_clock::now();
  try {
    sequence = visual_gyro::renderSequence(settings);
  } catch (const std::invalid_argument& e) {
    return usageError(e.what());
  }
  const double render_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  try {
    visual_gyro::writeKittiLayout(sequence, out);
  } catch (const std::exception& e) {
    std::cerr << "render_sequence: " << e.what() << "\n";
    return 1;
  }

  double total_deg = 0, max_deg = 0, yaw_deg = 0, path_m = 0;
  for (size_t k = 1; k < sequence.images.size(); ++k) {
    const Eigen::Matrix3d R = sequence.orientations[k - 1].transpose() * sequence.orientations[k];
    const double angle = Eigen::AngleAxisd(R).angle() * 180.0 / M_PI;
    total_deg += angle;
    max_deg = std::max(max_deg, angle);
    yaw_deg += std::atan2(R(0, 2), R(2, 2)) * 180.0 / M_PI;
    path_m += (sequence.positions[k] - sequence.positions[k - 1]).norm();
  }
  std::printf("render_sequence: preset %s, %d frames %dx%d at %.3g Hz, f = %.1f px -> %s\n",
              settings.preset.c_str(), settings.frames, settings.width, settings.height, settings.rate_hz,
              settings.fx, out.c_str());
  std::printf("  total rotation %.2f deg (max %.3f deg/frame, net yaw %+.2f deg), path length %.2f m, "
              "%.1f ms/frame (including scene set-up)\n",
              total_deg, max_deg, yaw_deg, path_m, render_ms / settings.frames);
  return 0;
}
