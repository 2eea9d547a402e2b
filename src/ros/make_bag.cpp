// make_bag: writes a rosbag from a sequence folder (KITTI odometry layout, EuRoC ASL layout, or a
// sequence rendered by render_sequence, which is KITTI layout with times.txt), for replay through
// the visual_gyro nodelet (launch/replay.launch, scripts/ros_demo.sh).
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "bag_tools.h"
#include "visual_gyro/sequence.h"

namespace {

void usage() {
  std::fprintf(stderr,
               "usage: make_bag <sequence folder> <output.bag> [options]\n"
               "  --max-frames N        write at most N frames (default: all)\n"
               "  --start SECONDS       first stamp of KITTI-layout sequences (default 1.0; ROS stamps must be > 0)\n"
               "  --camera-ns NS        image and camera_info topics NS/image_raw, NS/camera_info (default /camera)\n"
               "  --camera-frame ID     frame_id of the images (default camera_optical)\n"
               "  --compressed FORMAT   jpeg or png: sensor_msgs/CompressedImage on NS/image_raw/compressed\n"
               "                        instead of raw images (as image_transport's compressed plugin records)\n"
               "  --jpeg-quality Q      JPEG quality 1..100 (default 90, the compressed plugin's)\n"
               "Topics: NS/image_raw (mono8) or NS/image_raw/compressed, NS/camera_info, /imu/data (gyro, when the sequence has one),\n"
               "/ground_truth/pose (PoseStamped, camera -> first camera, when it has poses), /tf_static.\n");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    usage();
    return 2;
  }
  const std::string folder = argv[1], bag_path = argv[2];
  visual_gyro::bag_tools::BagWriteOptions options;
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "make_bag: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    try {
      if (a == "--max-frames") options.max_frames = std::stoi(value());
      else if (a == "--start") options.kitti_start = std::stod(value());
      else if (a == "--camera-ns") {
        std::string ns = value();
        while (!ns.empty() && ns.back() == '/') ns.pop_back();
        options.topics.image = ns + "/image_raw";
        options.topics.camera_info = ns + "/camera_info";
      } else if (a == "--camera-frame") options.topics.camera_frame = value();
      else if (a == "--compressed") {
        const std::string format = value();
        if (!visual_gyro::compressed_input::parseCompression(format, &options.compression)) {
          std::fprintf(stderr, "make_bag: --compressed takes jpeg or png, not '%s'\n", format.c_str());
          return 2;
        }
      } else if (a == "--jpeg-quality") options.jpeg_quality = std::stoi(value());
      else if (a == "-h" || a == "--help") {
        usage();
        return 0;
      } else {
        std::fprintf(stderr, "make_bag: unknown option '%s'\n", a.c_str());
        usage();
        return 2;
      }
    } catch (const std::logic_error&) {
      std::fprintf(stderr, "make_bag: bad value for %s\n", a.c_str());
      return 2;
    }
  }
  if (options.jpeg_quality < 1 || options.jpeg_quality > 100) {
    std::fprintf(stderr, "make_bag: --jpeg-quality must be in 1..100\n");
    return 2;
  }
  if (!(options.kitti_start > 0.0)) {
    std::fprintf(stderr, "make_bag: --start must be > 0 (ROS stamps must be positive)\n");
    return 2;
  }
  try {
    const visual_gyro::Sequence sequence = visual_gyro::loadSequence(folder);
    const auto summary = visual_gyro::bag_tools::writeSequenceBag(sequence, bag_path, options);
    namespace ci = visual_gyro::compressed_input;
    const std::string image_topic =
        options.compression == ci::Compression::kNone ? options.topics.image : options.topics.image + "/compressed";
    const std::string what = options.compression == ci::Compression::kJpeg
                                 ? " (JPEG, quality " + std::to_string(options.jpeg_quality) + ")"
                                 : options.compression == ci::Compression::kPng ? " (PNG)" : "";
    std::printf("make_bag: %s (%s layout) -> %s: %d images%s on %s (+ %s), %d ground-truth poses, %d gyro samples, "
                "stamps %.3f .. %.3f s\n",
                sequence.name.c_str(), sequence.layout.c_str(), bag_path.c_str(), summary.images, what.c_str(),
                image_topic.c_str(), options.topics.camera_info.c_str(), summary.poses, summary.gyro,
                summary.first_stamp, summary.last_stamp);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_bag: %s\n", e.what());
    return 1;
  }
  return 0;
}
