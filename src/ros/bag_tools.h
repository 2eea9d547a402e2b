// Rosbags of image sequences (writing from KITTI/EuRoC/rendered folders, reading for replay) and
// the evaluation of what the nodelet published against the bag's ground truth.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include "compressed_input.h"
#include "metrics.h"
#include "visual_gyro/RotationEstimate.h"
#include "visual_gyro/imu_alignment.h"
#include "visual_gyro/sequence.h"

namespace visual_gyro {
namespace bag_tools {

/// Topic and frame names of a sequence bag.
struct BagTopics {
  std::string image = "/camera/image_raw";           ///< sensor_msgs/Image, mono8 (or <image>/compressed)
  std::string camera_info = "/camera/camera_info";   ///< sensor_msgs/CameraInfo, same stamps
  std::string gyro = "/imu/data";                    ///< sensor_msgs/Imu (gyro only), when present
  std::string ground_truth = "/ground_truth/pose";   ///< geometry_msgs/PoseStamped, when present
  std::string camera_frame = "camera_optical";       ///< frame_id of images (optical: x right, y down, z fwd)
  std::string imu_frame = "imu";                     ///< frame_id of the gyro (EuRoC body frame)
  std::string world_frame = "world";                 ///< frame_id of ground-truth poses (first camera)
};

/// Options of writeSequenceBag.
struct BagWriteOptions {
  BagTopics topics;
  /// KITTI-layout stamps (relative, from times.txt or 10 Hz) are shifted to start here [s]: ROS
  /// stamps must be positive. EuRoC stamps are absolute and kept.
  double kitti_start = 1.0;
  int max_frames = 0;  ///< 0 = all
  /// kJpeg, kPng: images as sensor_msgs/CompressedImage on <image>/compressed instead of raw.
  compressed_input::Compression compression = compressed_input::Compression::kNone;
  int jpeg_quality = compressed_input::kDefaultJpegQuality;  ///< [0..100]
};

/// What was written.
struct BagWriteSummary {
  int images = 0, gyro = 0, poses = 0;
  double first_stamp = 0.0, last_stamp = 0.0;
};

/// Writes the sequence as a bag: per image an Image (mono8, the recorded stamp) and a CameraInfo
/// (with the real distortion: plumb_bob for radial-tangential), the ground-truth pose of each
/// image as PoseStamped (orientation = camera -> first camera, KITTI poses.txt convention) when the
/// sequence has poses, every gyro sample as Imu (body frame; no orientation/acceleration, marked
/// -1) when it has a gyro, and then a latched /tf_static with the camera's rotation in the gyro
/// frame (EuRoC T_BS). Throws std::runtime_error when an image cannot be read or the bag written.
BagWriteSummary writeSequenceBag(const Sequence& sequence, const std::string& bag_path,
                                 const BagWriteOptions& options);

/// An image (raw, or compressed when the bag holds <image>/compressed) with its camera_info (same
/// stamp; its header is also the image's).
struct BagFrame {
  sensor_msgs::ImageConstPtr image;                 ///< null for a compressed frame
  sensor_msgs::CompressedImageConstPtr compressed;  ///< null for a raw frame
  sensor_msgs::CameraInfoConstPtr info;
};

/// The messages of a sequence bag, in time order.
struct BagContents {
  std::vector<BagFrame> frames;
  std::vector<geometry_msgs::PoseStampedConstPtr> poses;
  std::vector<sensor_msgs::ImuConstPtr> gyro;
  std::vector<geometry_msgs::TransformStamped> static_transforms;
};

/// Reads a sequence bag (topics as named in `topics`; images raw on `image` or compressed on
/// `<image>/compressed`). Images without a camera_info of the same stamp are dropped. Throws std::runtime_error when the bag cannot be read or holds no images.
BagContents readSequenceBag(const std::string& bag_path, const BagTopics& topics = BagTopics());

/// Errors of the published estimates against the bag's ground truth (evaluate's JSON keys).
struct OutputSummary {
  std::string dataset, method, backend;
  /// Over the RotationEstimate messages (frames, invalid, with_truth: with ground truth for both
  /// stamps, the errors; rate RMSE against the gyro, else NaN), as the metrics module scores them.
  metrics::AccuracySummary accuracy;
  int imu_published = 0;   ///< Imu messages
  double detect_ms = NAN, describe_ms = NAN, match_ms = NAN, align_ms = NAN, estimate_ms = NAN, total_ms = NAN;
  double latency_ms = NAN;  ///< mean image-callback-to-publish wall time
  /// A gyro reference (a bag without poses) was aligned with the estimates first, as `evaluate`
  /// aligns it (eval::alignGyroTruth): gyro_alignment's offset and bias are removed from it.
  bool gyro_aligned = false;
  ImuAlignment gyro_alignment;

  /// One JSON object on one line (NaN -> null).
  std::string json() const;
  /// A few readable lines.
  std::string text() const;
};

/// Compares estimates (rotation in the camera optical frame, as published without ~output_frame)
/// with the truth in `truth`: per message R_true = R_gt(prev)^T R_gt(cur) from the poses, or, when
/// there are none, the gyro integrated between the two stamps and rotated into the camera frame with
/// the /tf_static rotation, after its bias and clock offset are removed (alignImu against the
/// estimates, the /tf_static rotation taken as known; the raw gyro when that fails). Scored with the metrics module, exactly as `evaluate` scores: an invalid
/// estimate counts as the identity; rotation error = angle of R_est^T R_true; yaw error =
/// difference of the yaws (about the camera's y axis, R = Ry Rx Rz).
OutputSummary evaluateOutputs(const std::vector<visual_gyro::RotationEstimate>& estimates, int imu_count,
                              const BagContents& truth, const std::string& dataset);

}  // namespace bag_tools
}  // namespace visual_gyro
