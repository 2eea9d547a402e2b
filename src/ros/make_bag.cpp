// make_bag: writes a rosbag from a sequence folder (KITTI odometry layout, EuRoC ASL layout, or a
// sequence rendered by render_sequence, which is KITTI layout with times.txt), for replay through
// the visual_gyro nodelet (launch/replay.launch, scripts/ros_demo.sh).
#include <cstdio>
#include <string>
#include <vector>

#include "bag_tools.h"
#include "command_line.h"
#include "visual_gyro/sequence.h"

namespace {

const char* const kUsage =
    "usage: make_bag <sequence folder> <output.bag> [options]\n"
    "  --max-frames N        write at most N frames (default: all)\n"
    "  --start SECONDS       first stamp of KITTI-layout sequences (default 1.0; ROS stamps must be > 0)\n"
    "  --camera-ns NS        image and camera_info topics NS/image_raw, NS/camera_info (default /camera)\n"
    "  --camera-frame ID     frame_id of the images (default camera_optical)\n"
    "  --compressed FORMAT   jpeg or png: sensor_msgs/CompressedImage on NS/image_raw/compressed\n"
    "                        instead of raw images (as image_transport's compressed plugin records)\n"
    "  --jpeg-quality Q      JPEG quality 1..100 (default 90, the compressed plugin's)\n"
    "Topics: NS/image_raw (mono8) or NS/image_raw/compressed, NS/camera_info, /imu/data (gyro, when the sequence has one),\n"
    "/ground_truth/pose (PoseStamped, camera -> first camera, when it has poses), /tf_static.\n";

int run(int argc, char** argv) {
  using visual_gyro::cli::UsageError;
  std::vector<std::string> positional;
  visual_gyro::bag_tools::BagWriteOptions options;
  for (visual_gyro::cli::Arguments args(argc, argv); args.next();) {
    if (args.is("-h") || args.is("--help")) {
      std::printf("%s", kUsage);
      return 0;
    } else if (args.is("--max-frames")) {
      options.max_frames = static_cast<int>(args.intValue(1, 100000000));
    } else if (args.is("--start")) {
      options.kitti_start = args.doubleValue(1e-9, 4e9);
    } else if (args.is("--camera-ns")) {
      std::string ns = args.value();
      while (!ns.empty() && ns.back() == '/') ns.pop_back();
      options.topics.image = ns + "/image_raw";
      options.topics.camera_info = ns + "/camera_info";
    } else if (args.is("--camera-frame")) {
      options.topics.camera_frame = args.value();
    } else if (args.is("--compressed")) {
      const std::string format = args.value();
      if (!visual_gyro::compressed_input::parseCompression(format, &options.compression))
        throw UsageError("--compressed takes jpeg or png, not '" + format + "'");
    } else if (args.is("--jpeg-quality")) {
      options.jpeg_quality = static_cast<int>(args.intValue(1, 100));
    } else {
      args.positional(&positional, 2);
    }
  }
  if (positional.size() != 2) throw UsageError("a sequence folder and an output bag are needed");
  const std::string folder = positional[0], bag_path = positional[1];
  {
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
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return visual_gyro::cli::runCommand("make_bag", kUsage, [&] { return run(argc, argv); }); }
