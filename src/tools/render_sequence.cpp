// render_sequence: renders a synthetic sequence with known motion and writes it in the KITTI
// odometry layout (image_l/*.png, calib.txt, poses.txt, times.txt).
#include <chrono>
#include <cstdio>
#include <iostream>
#include <string>

#include "command_line.h"
#include "visual_gyro/geometry.h"
#include "visual_gyro/renderer.h"

namespace visual_gyro {
namespace {

using cli::UsageError;

const char* const kUsage =
    "usage: render_sequence --preset drive|handheld|forward|dim|drone_near|handheld_rs --out DIR [options]\n"
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
    "  --rolling-shutter-ms T  rows exposed one after another over T ms, row r at\n"
    "                  stamp + (r / (H - 1) - 0.5) T: the stamp and pose of a frame are its middle\n"
    "                  row's (default 0: global shutter; handheld_rs: 28)\n"
    "  --hand-translation-cm A  handheld, dim: the hand moves the camera by +-A cm along x and z,\n"
    "                  2/3 of it along y (default 0.3: held still)\n"
    "Presets: drive = car at 10 m/s with a right and a left turn (up to 30 deg/s); handheld =\n"
    "rotation about all axes (up to ~40 deg/s) in a room, mm jitter; forward = straight drive;\n"
    "dim = the handheld motion in a dim room of plain walls, doors and boxes (30 grey levels);\n"
    "drone_near = a drone shaken by hand 1-2 m from boxes and walls (20 Hz); handheld_rs =\n"
    "handheld with a phone-like rolling shutter (28 ms read-out at 30 Hz).\n"
    "Poses are camera -> first camera (x right, y down, z forward), positions in metres.\n";

/// A preset of the renderer seen through a rolling shutter.
struct RollingShutterPreset {
  const char* name;
  RenderPreset preset;
  double read_out_ms;  ///< rolling_shutter_s in ms
};
/// A phone filmed by hand: 30 Hz frames read out over 28 ms (phone sensors take about 20-33 ms).
constexpr RollingShutterPreset kRollingShutterPresets[] = {{"handheld_rs", RenderPreset::kHandheld, 28.0}};

/// Reads a preset name, the renderer's or a rolling-shutter one (which sets *read_out_ms).
bool parseAnyPreset(const std::string& name, RenderPreset* preset, double* read_out_ms) {
  for (const auto& p : kRollingShutterPresets) {
    if (name == p.name) {
      *preset = p.preset;
      *read_out_ms = p.read_out_ms;
      return true;
    }
  }
  return parsePreset(name, preset);
}

int run(int argc, char** argv) {
  RenderSettings settings;
  std::string out, preset_name;
  bool preset_given = false, rate_given = false, shutter_given = false;
  double preset_read_out_ms = 0.0, read_out_ms = 0.0;
  for (cli::Arguments args(argc, argv); args.next();) {
    if (args.is("--help") || args.is("-h")) {
      std::cout << kUsage;
      return 0;
    } else if (args.is("--preset")) {
      preset_name = args.value();
      if (!parseAnyPreset(preset_name, &settings.preset, &preset_read_out_ms))
        throw UsageError("unknown preset '" + preset_name + "'");
      preset_given = true;
    } else if (args.is("--out") || args.is("--output")) {
      out = args.value();
    } else if (args.is("--frames")) {
      settings.frames = static_cast<int>(args.intValue(1, 1000000));
    } else if (args.is("--width")) {
      settings.width = static_cast<int>(args.intValue(8, 16384));
    } else if (args.is("--height")) {
      settings.height = static_cast<int>(args.intValue(8, 16384));
    } else if (args.is("--focal")) {
      settings.fx = settings.fy = args.doubleValue(1e-6, 1e9);
    } else if (args.is("--rate")) {
      settings.rate_hz = args.doubleValue(1e-6, 1e9);
      rate_given = true;
    } else if (args.is("--noise")) {
      settings.noise_sigma = args.doubleValue(0.0, 1e9);
    } else if (args.is("--contrast")) {
      settings.contrast = args.doubleValue(1e-9, 100.0);
    } else if (args.is("--blur")) {
      settings.blur_px = args.doubleValue(0.0, 200.0);
    } else if (args.is("--jpeg")) {
      settings.jpeg_quality = static_cast<int>(args.intValue(1, 100));
    } else if (args.is("--rolling-shutter-ms")) {
      read_out_ms = args.doubleValue(0.0, 1e9);
      shutter_given = true;
    } else if (args.is("--hand-translation-cm")) {
      settings.hand_translation_m = 0.01 * args.doubleValue(0.0, 100.0);
    } else if (args.is("--seed")) {
      settings.seed = static_cast<uint64_t>(args.intValue(0, 9223372036854775807LL));
    } else {
      args.unexpected();
    }
  }
  if (!preset_given) throw UsageError("--preset is required");
  if (out.empty()) throw UsageError("--out is required");
  if (!rate_given) settings.rate_hz = presetRateHz(settings.preset);
  settings.rolling_shutter_s = 1e-3 * (shutter_given ? read_out_ms : preset_read_out_ms);
  settings.setCentredCamera(settings.width, settings.height, settings.fx);

  RenderedSequence sequence;
  const auto start = std::chrono::steady_clock::now();
  try {
    sequence = renderSequence(settings);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  const double render_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  writeKittiLayout(sequence, out);

  double total_deg = 0, max_deg = 0, yaw_deg = 0, path_m = 0;
  for (size_t k = 1; k < sequence.images.size(); ++k) {
    const Eigen::Matrix3d R = sequence.orientations[k - 1].transpose() * sequence.orientations[k];
    const double angle = rotationAngle(R) * kRadToDeg;
    total_deg += angle;
    max_deg = std::max(max_deg, angle);
    yaw_deg += yawPitchRollFromRotation(R)[0] * kRadToDeg;
    path_m += (sequence.positions[k] - sequence.positions[k - 1]).norm();
  }
  std::printf("render_sequence: preset %s, %d frames %dx%d at %.3g Hz, f = %.1f px, rolling shutter %.3g ms -> %s\n",
              preset_name.c_str(), settings.frames, settings.width, settings.height, settings.rate_hz, settings.fx,
              1e3 * settings.rolling_shutter_s, out.c_str());
  std::printf("  total rotation %.2f deg (max %.3f deg/frame, net yaw %+.2f deg), path length %.2f m, "
              "%.1f ms/frame (including scene set-up)\n",
              total_deg, max_deg, yaw_deg, path_m, render_ms / settings.frames);
  return 0;
}

}  // namespace
}  // namespace visual_gyro

int main(int argc, char** argv) {
  return visual_gyro::cli::runCommand("render_sequence", visual_gyro::kUsage,
                                      [&] { return visual_gyro::run(argc, argv); });
}
