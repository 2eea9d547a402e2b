// Synthetic sequence renderer: textured planes at several depths seen along a known trajectory.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <cstdint>
#include <string>
#include <vector>

namespace visual_gyro {

/// The scene and motion of a rendered sequence.
enum class RenderPreset {
  kDrive,     ///< car-like forward motion with left and right turns (10 Hz)
  kHandheld,  ///< rotation only with small jitter, in a textured room (30 Hz)
  kForward,   ///< straight forward drive, no rotation to speak of (10 Hz)
  /// The handheld motion in a dim room of large plain walls, a few doors and boxes, all within 30
  /// grey levels (30 Hz).
  kDim,
  /// A hand-shaken camera 1-2 m from textured structure: up to ~3 deg and 2-5 cm per frame at
  /// 20 Hz, strong parallax.
  kDroneNear,
};

/// "drive", "handheld", "forward", "dim" or "drone_near".
const char* presetName(RenderPreset preset);
/// Reads a preset name; false (and *preset untouched) for an unknown one.
bool parsePreset(const std::string& name, RenderPreset* preset);
/// The frame rate a preset is meant for [Hz] (10, 30 or 20).
double presetRateHz(RenderPreset preset);

/// The room presets' hand translation by default [m]: a hand holding the camera still.
constexpr double kStillHandTranslationM = 0.003;

/// What to render.
struct RenderSettings {
  RenderPreset preset = RenderPreset::kDrive;
  int frames = 60;
  int width = 640;
  int height = 480;
  double fx = 500.0, fy = 500.0, cx = 319.5, cy = 239.5;
  double rate_hz = 10.0;       ///< frame rate: stamps are k / rate_hz [s]
  double noise_sigma = 2.0;    ///< Gaussian pixel noise (grey levels)
  uint64_t seed = 7;           ///< texture and noise seed
  // Degradations, applied in this order to the rendered image: contrast, motion blur, noise, JPEG.
  double contrast = 1.0;       ///< grey levels scaled about the image mean by this factor (> 0)
  /// Motion blur: a line kernel this long [px], along the image motion of the principal point
  /// over one frame interval centred on the frame (so the pose stays the frame's); 0 = none.
  /// renderView() knows no motion and blurs along +x.
  double blur_px = 0.0;
  int jpeg_quality = 0;        ///< JPEG-compressed and decoded at this quality (1..100); 0 = none
  /// Rolling shutter: the rows are exposed one after another over this time [s], in [0, 1 / rate_hz].
  /// Row r (0 = top) is seen from the pose at stamp + (r / (height - 1) - 0.5) * rolling_shutter_s:
  /// a frame's stamp, and its pose in RenderedSequence, are its middle row's. 0 = global shutter.
  double rolling_shutter_s = 0.0;
  /// Room presets (handheld, dim): amplitude [m] of the hand's translation along x and z (y: two
  /// thirds of it), each a sine of about 1.1-1.7 Hz: a few millimetres, a hand holding the camera
  /// still; a few centimetres, a hand moving it. Other presets ignore it.
  double hand_translation_m = kStillHandTranslationM;

  /// Sets the image size [px] and a pinhole camera with fx = fy = `focal` [px] whose principal
  /// point is the image centre ((width - 1) / 2, (height - 1) / 2).
  void setCentredCamera(int image_width, int image_height, double focal) {
    width = image_width;
    height = image_height;
    fx = fy = focal;
    cx = (image_width - 1) / 2.0;
    cy = (image_height - 1) / 2.0;
  }
};

/// Degradations of one image, applied in this order: gain, contrast, motion blur, noise, stuck
/// pixels, JPEG. The
/// renderer applies them to what it renders (RenderSettings' fields); the evaluation applies them
/// to real footage (`evaluate --gain-jitter/--contrast/--noise/--stuck-pixels/--jpeg`).
struct ImageDegradation {
  double gain_jitter = 0.0;   ///< grey levels times 1 + u, u uniform in [-gain_jitter, gain_jitter], one draw
                              ///< per image (an automatic exposure stepping between frames), in [0, 0.9]
  double contrast = 1.0;      ///< grey levels scaled about the image mean by this factor, in (0, 100]
  double blur_px = 0.0;       ///< line blur this long [px] along blur_direction, in [0, 200]; 0 = none
  Eigen::Vector2d blur_direction = Eigen::Vector2d::UnitX();  ///< image x right, y down; unit length
  double noise_sigma = 0.0;   ///< Gaussian pixel noise [grey levels], >= 0
  int stuck_pixels = 0;       ///< this many pixels stuck at white, after the noise and before the JPEG, at the
                              ///< same places in every image of a size (a sensor's hot pixels), in [0, 100000]
  int jpeg_quality = 0;       ///< JPEG-compressed and decoded at this quality (1..100); 0 = none

  /// True when at least one degradation changes an image.
  bool any() const {
    return gain_jitter > 0.0 || contrast != 1.0 || blur_px > 0.0 || noise_sigma > 0.0 || stuck_pixels > 0 ||
           jpeg_quality > 0;
  }
};

/// Throws std::invalid_argument, its message starting with `who`, when a value of `degradation`
/// is out of the range its field states.
void checkDegradation(const ImageDegradation& degradation, const std::string& who);

/// `image` (CV_8UC1, or CV_32FC1 grey levels) degraded by `degradation`: rounded to CV_8UC1 after
/// the noise, whose normal draws come from `noise_seed` pixel by pixel in row order; the gain's
/// draw comes from a stream of its own, so that it leaves the noise's draws as they are. Throws
/// std::invalid_argument for another image type or a value out of range.
cv::Mat degradeImage(const cv::Mat& image, const ImageDegradation& degradation, uint64_t noise_seed);

/// Rendered sequence in memory.
struct RenderedSequence {
  std::vector<cv::Mat> images;               ///< CV_8UC1
  std::vector<Eigen::Matrix3d> orientations;  ///< camera -> world (first camera) per frame
  std::vector<Eigen::Vector3d> positions;     ///< [m]
  std::vector<double> stamps;                 ///< [s]
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
};

/// Renders the preset. Throws std::invalid_argument for an unknown preset or bad sizes.
RenderedSequence renderSequence(const RenderSettings& settings);

/// The pose of the preset's motion at time t [s] (t = 0: the first frame; negative t before it):
/// orientation camera -> world (world = the first camera's frame: x right, y down, z forward),
/// position [m]. The drive presets' path depends on settings.frames and rate_hz. Throws
/// std::invalid_argument for settings renderSequence() refuses or a non-finite t.
void presetPose(const RenderSettings& settings, double t, Eigen::Matrix3d* orientation, Eigen::Vector3d* position);

/// Renders one view of the preset's scene at an arbitrary pose (camera -> world).
cv::Mat renderView(const RenderSettings& settings, const Eigen::Matrix3d& orientation,
                   const Eigen::Vector3d& position);

/// Writes the KITTI odometry layout: image_l/000000.png ..., calib.txt, poses.txt, times.txt, and
/// truth_sigma_deg.txt = 0 (the poses are exact).
/// Throws std::runtime_error when the folder cannot be written.
void writeKittiLayout(const RenderedSequence& sequence, const std::string& folder);

}  // namespace visual_gyro
