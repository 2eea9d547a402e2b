// calibrate_imu: aligns the visual gyro with a real IMU. Runs the pipeline over the images of a
// EuRoC-layout folder (cam0/ and imu0/) or of a rosbag (an image topic and an Imu topic) and
// estimates the clocks' offset, the camera's rotation in the IMU frame and the gyro's bias (and
// scale with --scale) with the core's alignment (visual_gyro/imu_alignment.h). Prints a summary,
// snippets to paste (node parameter, static tf, bias) and, last, one JSON line.
//
// Exit status: 0 done (also when something is not observable: it says so and gives null), 1 data
// problem (no IMU, IMU stamps not increasing or not overlapping the images, an IMU too slow,
// unreadable images), 2 bad command line.

#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "alignment_bag.h"
#include "command_line.h"
#include "imu_alignment_report.h"
#include "json_writer.h"
#include "visual_gyro/imu_alignment.h"
#include "visual_gyro/sequence.h"
#include "visual_gyro/visual_gyro.h"

namespace visual_gyro {
namespace {

using cli::UsageError;

std::string fixed(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", v);
  return buf;
}

std::string usage() {
  const alignment_bag::Topics topics = alignment_bag::withDefaults({});
  const ImuAlignmentSettings defaults;
  return "usage: calibrate_imu <EuRoC folder | file.bag> [options]\n"
         "  A EuRoC-layout folder needs cam0/ (data.csv, data/, sensor.yaml) and imu0/data.csv;\n"
         "  a bag needs an image topic (raw, or <topic>/compressed), its camera_info and an Imu topic.\n"
         "  --image-topic T        bag: images (default " + topics.image + ")\n"
         "  --imu-topic T          bag: sensor_msgs/Imu (default " + topics.imu + ")\n"
         "  --camera-info-topic T  bag: camera_info (default: beside the image topic)\n"
         "  --max-offset MS        offsets searched in [-MS, MS] milliseconds (default " +
         std::to_string(static_cast<int>(defaults.max_offset * 1e3)) + ")\n"
         "  --max-offset-sigma MS  a less certain offset is reported not observable (default " +
         fixed(defaults.max_offset_sigma * 1e3) + ")\n"
         "  --max-rotation-sigma DEG  a rotation less certain about any axis is not observable (default " +
         fixed(defaults.max_rotation_sigma_deg) + ")\n"
         "  --scale                also estimate the gyro's per-axis scale\n"
         "  --frames N             use at most the first N images\n"
         "  --backend B            auto, cpu or cuda (default auto)\n"
         "  --camera-frame ID      camera frame_id in the static tf line (default: the bag's, else camera_optical)\n"
         "  --imu-frame ID         IMU frame_id in the static tf line (default: the bag's, else imu)\n"
         "  --quiet                no progress\n"
         "Conventions: t_imu = t_camera + time_offset; omega_imu = R_imu_from_camera * omega_camera;\n"
         "bias in the IMU frame [rad/s]. See doc/imu_alignment.md.\n";
}

struct Options {
  std::string input;
  alignment_bag::Topics topics;
  ImuAlignmentSettings alignment;
  long long frames = -1;
  std::string backend;
  std::string camera_frame, imu_frame;
  bool quiet = false;
};

Options parseOptions(int argc, char** argv) {
  Options o;
  bool have_input = false;
  for (cli::Arguments args(argc, argv); args.next();) {
    if (args.is("-h") || args.is("--help")) {
      std::cout << usage();
      std::exit(0);
    } else if (args.is("--image-topic")) {
      o.topics.image = args.value();
    } else if (args.is("--imu-topic")) {
      o.topics.imu = args.value();
    } else if (args.is("--camera-info-topic")) {
      o.topics.camera_info = args.value();
    } else if (args.is("--max-offset")) {
      o.alignment.max_offset = args.doubleValue(1.0, 10000.0) * 1e-3;
    } else if (args.is("--max-offset-sigma")) {
      o.alignment.max_offset_sigma = args.doubleValue(1e-3, 1000.0) * 1e-3;
    } else if (args.is("--max-rotation-sigma")) {
      o.alignment.max_rotation_sigma_deg = args.doubleValue(1e-3, 180.0);
    } else if (args.is("--scale")) {
      o.alignment.estimate_scale = true;
    } else if (args.is("--frames")) {
      o.frames = args.intValue(2, 1000000000);
    } else if (args.is("--backend")) {
      o.backend = args.value();
      BackendChoice choice;
      if (!parseBackendChoice(o.backend, &choice))
        throw UsageError("--backend must be auto, cpu or cuda, not '" + o.backend + "'");
    } else if (args.is("--camera-frame")) {
      o.camera_frame = args.value();
    } else if (args.is("--imu-frame")) {
      o.imu_frame = args.value();
    } else if (args.is("--quiet")) {
      o.quiet = true;
    } else if (args.isOption() || have_input) {
      args.unexpected();
    } else {
      o.input = args.current();
      have_input = true;
    }
  }
  if (!have_input) throw UsageError("no EuRoC folder or bag given");
  return o;
}

bool sameCamera(const CameraModel& a, const CameraModel& b) {
  return a.fx() == b.fx() && a.fy() == b.fy() && a.cx() == b.cx() && a.cy() == b.cy() && a.width() == b.width() &&
         a.height() == b.height() && a.distortionModel() == b.distortionModel() && a.distortion() == b.distortion();
}

/// Runs the pipeline image by image and keeps every frame interval.
class RateCollector {
 public:
  RateCollector(const VisualGyroSettings& settings, bool progress) : settings_(settings), progress_(progress) {}

  void add(const cv::Mat& gray, double stamp, const CameraModel& camera) {
    if (!gyro_ || !sameCamera(camera, gyro_->camera())) {
      // An unusable calibration would give wrong rates, not none: refuse it.
      std::string problem = camera.validate();
      if (problem.empty()) problem = calibrationProblem(camera);
      if (!problem.empty()) throw std::runtime_error("camera model unusable: " + problem);
      if (gyro_) {
        gyro_->setCamera(camera);
      } else {
        const WarningSink warn = [](const std::string& w) { std::cerr << "warning: " << w << "\n"; };
        gyro_.reset(new VisualGyro(camera, settings_, warn));
      }
    }
    const FrameResult result = gyro_->processFrame(gray, stamp);
    ++images_;
    if (result.skipped() && skipped_++ == 0) first_skip_ = result.reason;
    VisualRate rate;
    if (visualRateOf(result, stamp, &rate)) rates_.push_back(rate);
    if (progress_) std::fprintf(stderr, "\r[calibrate_imu] image %d, %zu frame intervals   ", images_, rates_.size());
  }

  const std::vector<VisualRate>& rates() const { return rates_; }
  int images() const { return images_; }
  /// Says on stderr how many images the pipeline skipped and why (the first).
  void reportSkips() const {
    if (progress_) std::fprintf(stderr, "\n");
    if (skipped_ > 0)
      std::fprintf(stderr, "[calibrate_imu] %d image(s) skipped by the pipeline (first: %s)\n", skipped_,
                   first_skip_.c_str());
  }

 private:
  VisualGyroSettings settings_;
  bool progress_;
  std::unique_ptr<VisualGyro> gyro_;
  std::vector<VisualRate> rates_;
  int images_ = 0, skipped_ = 0;
  std::string first_skip_;
};

/// The EuRoC folder: its IMU checked against the image stamps before any image is processed.
std::vector<GyroSample> runFolder(const Options& o, RateCollector* collector, eval::AlignmentSource* source) {
  const Sequence seq = loadSequence(o.input);
  if (seq.layout != "euroc")
    throw std::runtime_error(o.input + ": not a EuRoC-layout folder (cam0/ and imu0/); give a bag for other data");
  if (!seq.hasGyro()) throw std::runtime_error(o.input + ": no IMU (imu0/data.csv is missing or empty)");
  size_t count = seq.image_paths.size();
  if (o.frames > 0) count = std::min(count, static_cast<size_t>(o.frames));
  const std::vector<double> stamps(seq.stamps.begin(), seq.stamps.begin() + count);
  checkImuSamples(seq.gyro, stamps, o.alignment);
  for (size_t k = 0; k < count; ++k) {
    const cv::Mat gray = cv::imread(seq.image_paths[k], cv::IMREAD_GRAYSCALE);
    if (gray.empty()) throw std::runtime_error("cannot read image " + seq.image_paths[k]);
    collector->add(gray, seq.stamps[k], seq.camera);
  }
  source->dataset = seq.name;
  source->camera_frame = o.camera_frame.empty() ? "camera_optical" : o.camera_frame;
  source->imu_frame = o.imu_frame.empty() ? "imu" : o.imu_frame;
  source->has_reference_rotation = true;
  source->reference_rotation = seq.body_from_camera;
  return seq.gyro;
}

/// The bag: a first pass reads the IMU and the image stamps, which are checked before the images
/// are decoded and processed in a second pass.
std::vector<GyroSample> runBag(const Options& o, RateCollector* collector, eval::AlignmentSource* source) {
  const alignment_bag::Scan scan = alignment_bag::scanBag(o.input, o.topics);
  if (scan.imu.empty())
    throw std::runtime_error(o.input + ": no sensor_msgs/Imu on " + alignment_bag::withDefaults(o.topics).imu);
  std::vector<double> stamps = scan.image_stamps;
  if (o.frames > 0 && stamps.size() > static_cast<size_t>(o.frames)) stamps.resize(o.frames);
  checkImuSamples(scan.imu, stamps, o.alignment);
  long long taken = 0;
  std::string problem;
  const int skipped = alignment_bag::forEachImage(
      o.input, o.topics,
      [&](const cv::Mat& gray, double stamp, const CameraModel& camera) {
        if (o.frames < 0 || taken++ < o.frames) collector->add(gray, stamp, camera);
      },
      &problem);
  if (skipped > 0)
    std::fprintf(stderr, "[calibrate_imu] %d image(s) not decoded (first: %s)\n", skipped, problem.c_str());
  source->dataset = o.input.substr(o.input.find_last_of('/') + 1);
  source->camera_frame = !o.camera_frame.empty() ? o.camera_frame
                         : scan.camera_frame.empty() ? "camera_optical" : scan.camera_frame;
  source->imu_frame = !o.imu_frame.empty() ? o.imu_frame : scan.imu_frame.empty() ? "imu" : scan.imu_frame;
  source->has_reference_rotation = scan.has_imu_from_camera;
  source->reference_rotation = scan.imu_from_camera;
  return scan.imu;
}

bool isBag(const std::string& path) { return path.size() > 4 && path.compare(path.size() - 4, 4, ".bag") == 0; }

int run(int argc, char** argv) {
  const Options o = parseOptions(argc, argv);
  cv::setNumThreads(1);
  VisualGyroSettings settings;
  if (!o.backend.empty()) parseBackendChoice(o.backend, &settings.estimator.backend);
  RateCollector collector(settings, !o.quiet && isatty(fileno(stderr)));
  eval::AlignmentSource source;
  const std::vector<GyroSample> imu =
      isBag(o.input) ? runBag(o, &collector, &source) : runFolder(o, &collector, &source);
  collector.reportSkips();
  source.images = collector.images();
  const ImuAlignment alignment = alignImu(collector.rates(), imu, o.alignment);
  std::cout << eval::alignmentText(alignment, source) << "\n" << eval::alignmentSnippets(alignment, source) << "\n";
  JsonObject json;
  eval::addAlignmentFields(alignment, source, &json);
  std::cout << json.str() << std::endl;
  return 0;
}

}  // namespace
}  // namespace visual_gyro

int main(int argc, char** argv) {
  return visual_gyro::cli::runCommand("calibrate_imu", visual_gyro::usage(),
                                      [&] { return visual_gyro::run(argc, argv); });
}
