#include "bag_tools.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <map>
#include <sstream>
#include <stdexcept>

#include <Eigen/Geometry>
#include <boost/make_shared.hpp>
#include <opencv2/imgcodecs.hpp>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/image_encodings.h>
#include <tf2_msgs/TFMessage.h>

#include "imu_alignment_report.h"
#include "json_writer.h"
#include "metrics.h"
#include "ros_conversions.h"
#include "visual_gyro/geometry.h"
#include "visual_gyro/rotation_estimator.h"

namespace visual_gyro {
namespace bag_tools {

namespace conv = ros_conversions;

namespace {

ros::Time toRosTime(double seconds) {
  ros::Time t;
  t.fromSec(seconds);
  return t;
}

/// Connection header of a latched topic (rosbag play re-publishes it latched, as /tf_static needs).
template <typename M>
boost::shared_ptr<ros::M_string> latchedHeader(const std::string& topic) {
  auto header = boost::make_shared<ros::M_string>();
  (*header)["topic"] = topic;
  (*header)["type"] = ros::message_traits::datatype<M>();
  (*header)["md5sum"] = ros::message_traits::md5sum<M>();
  (*header)["message_definition"] = ros::message_traits::definition<M>();
  (*header)["callerid"] = "/make_bag";
  (*header)["latching"] = "1";
  return header;
}

/// Writes a sequence's gyro samples as Imu messages (gyro only: no orientation or acceleration,
/// marked -1) in time order, each call up to a time, so that they interleave with the images
/// (rosbag play publishes by bag time). Samples whose shifted stamp is not positive are dropped.
class GyroBagWriter {
 public:
  /// `offset` [s] shifts the sequence's stamps to bag stamps; `written` counts the messages.
  GyroBagWriter(const Sequence& sequence, const BagTopics& topics, double offset, rosbag::Bag* bag, int* written)
      : sequence_(sequence), topics_(topics), offset_(offset), bag_(bag), written_(written) {}

  /// Writes the samples not written yet whose stamp (sequence time) is at most t_limit [s].
  void writeUntil(double t_limit) {
    for (; next_ < sequence_.gyro.size() && sequence_.gyro[next_].stamp <= t_limit; ++next_) {
      const GyroSample& g = sequence_.gyro[next_];
      sensor_msgs::Imu imu;
      imu.header.stamp = toRosTime(g.stamp + offset_);
      imu.header.frame_id = topics_.imu_frame;
      imu.orientation.w = 1.0;
      imu.orientation_covariance[0] = -1.0;
      imu.linear_acceleration_covariance[0] = -1.0;
      imu.angular_velocity.x = g.angular_velocity.x();
      imu.angular_velocity.y = g.angular_velocity.y();
      imu.angular_velocity.z = g.angular_velocity.z();
      if (imu.header.stamp.toSec() > 0.0) {
        bag_->write(topics_.gyro, imu.header.stamp, imu);
        ++*written_;
      }
    }
  }

 private:
  const Sequence& sequence_;
  const BagTopics& topics_;
  double offset_;
  rosbag::Bag* bag_;
  int* written_;
  size_t next_ = 0;
};

/// The camera's rotation in the gyro frame as a latched /tf_static stamped `stamp`.
void writeCameraInGyroFrame(const Sequence& sequence, const BagTopics& topics, const ros::Time& stamp,
                            rosbag::Bag* bag) {
  tf2_msgs::TFMessage tf;
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = topics.imu_frame;
  t.child_frame_id = topics.camera_frame;
  t.transform.rotation = conv::toMsg(Eigen::Quaterniond(sequence.body_from_camera));
  tf.transforms.push_back(t);
  bag->write("/tf_static", stamp, tf, latchedHeader<tf2_msgs::TFMessage>("/tf_static"));
}

/// Image k of the sequence, grey; std::runtime_error when it cannot be read or is not the
/// calibration's size.
cv::Mat readSequenceImage(const Sequence& sequence, size_t k) {
  cv::Mat gray = cv::imread(sequence.image_paths[k], cv::IMREAD_GRAYSCALE);
  if (gray.empty()) throw std::runtime_error("cannot read image '" + sequence.image_paths[k] + "'");
  if (gray.cols != sequence.camera.width() || gray.rows != sequence.camera.height()) {
    throw std::runtime_error("image '" + sequence.image_paths[k] + "' is " + std::to_string(gray.cols) + "x" +
                             std::to_string(gray.rows) + ", the calibration says " +
                             std::to_string(sequence.camera.width()) + "x" +
                             std::to_string(sequence.camera.height()));
  }
  return gray;
}

/// Writes image k's ground-truth pose stamped `stamp`; false (nothing written) when the sequence
/// has none for it (images outside the ground truth's time span have NaN poses).
bool writeGroundTruthPose(const Sequence& sequence, size_t k, const ros::Time& stamp, const BagTopics& topics,
                          rosbag::Bag* bag) {
  if (!sequence.hasPoses() || k >= sequence.orientations.size() || !sequence.orientations[k].allFinite()) {
    return false;
  }
  geometry_msgs::PoseStamped pose;
  pose.header.stamp = stamp;
  pose.header.frame_id = topics.world_frame;
  pose.pose.orientation = conv::toMsg(Eigen::Quaterniond(sequence.orientations[k]));
  if (k < sequence.positions.size()) {
    pose.pose.position.x = sequence.positions[k].x();
    pose.pose.position.y = sequence.positions[k].y();
    pose.pose.position.z = sequence.positions[k].z();
  }
  bag->write(topics.ground_truth, stamp, pose);
  return true;
}

/// Writes `gray` with its camera info (whose header, stamp and seq set, it shares): compressed on
/// <image>/compressed when the options say so, else raw mono8 on <image>.
void writeImage(const cv::Mat& gray, const sensor_msgs::CameraInfo& info, const BagWriteOptions& options,
                rosbag::Bag* bag) {
  const BagTopics& topics = options.topics;
  const ros::Time& stamp = info.header.stamp;
  if (options.compression != compressed_input::Compression::kNone) {
    sensor_msgs::CompressedImage compressed =
        compressed_input::encodeGray(gray, options.compression, options.jpeg_quality);
    compressed.header = info.header;
    bag->write(topics.camera_info, stamp, info);
    bag->write(topics.image + "/compressed", stamp, compressed);
    return;
  }
  sensor_msgs::Image image;
  image.header.stamp = stamp;
  image.header.frame_id = topics.camera_frame;
  image.header.seq = info.header.seq;
  image.height = static_cast<uint32_t>(gray.rows);
  image.width = static_cast<uint32_t>(gray.cols);
  image.encoding = sensor_msgs::image_encodings::MONO8;
  image.is_bigendian = 0;
  image.step = static_cast<uint32_t>(gray.cols);
  image.data.resize(static_cast<size_t>(gray.rows) * gray.cols);
  for (int r = 0; r < gray.rows; ++r) std::copy(gray.ptr<uint8_t>(r), gray.ptr<uint8_t>(r) + gray.cols, &image.data[r * gray.cols]);
  bag->write(topics.camera_info, stamp, info);
  bag->write(topics.image, stamp, image);
}

}  // namespace

BagWriteSummary writeSequenceBag(const Sequence& sequence, const std::string& bag_path,
                                 const BagWriteOptions& options) {
  const BagTopics& topics = options.topics;
  size_t count = sequence.image_paths.size();
  if (options.max_frames > 0) count = std::min(count, static_cast<size_t>(options.max_frames));
  if (count == 0) throw std::runtime_error("sequence '" + sequence.name + "' has no images");
  if (sequence.stamps.size() < count)
    throw std::runtime_error("sequence '" + sequence.name + "' has fewer stamps than images");

  // KITTI stamps are relative to the start of the sequence (or implied by 10 Hz).
  const bool relative = sequence.layout != "euroc";
  const double offset = relative ? options.kitti_start - sequence.stamps[0] : 0.0;
  auto stampOf = [&](double t) { return t + offset; };

  rosbag::Bag bag;
  try {
    bag.open(bag_path, rosbag::bagmode::Write);
  } catch (const rosbag::BagException& e) {
    throw std::runtime_error("cannot write bag '" + bag_path + "': " + e.what());
  }
  BagWriteSummary summary;
  summary.first_stamp = stampOf(sequence.stamps[0]);
  summary.last_stamp = stampOf(sequence.stamps[count - 1]);

  sensor_msgs::CameraInfo info = conv::cameraInfoFromModel(sequence.camera);
  info.header.frame_id = topics.camera_frame;

  GyroBagWriter gyro(sequence, topics, offset, &bag, &summary.gyro);
  const double gyro_end = summary.last_stamp - offset;
  // First in the bag.
  if (sequence.hasGyro()) writeCameraInGyroFrame(sequence, topics, toRosTime(summary.first_stamp), &bag);

  for (size_t k = 0; k < count; ++k) {
    const double t_seq = sequence.stamps[k];
    const ros::Time stamp = toRosTime(stampOf(t_seq));
    if (!(stamp.toSec() > 0.0)) throw std::runtime_error("stamp of image " + std::to_string(k) + " is not positive");
    gyro.writeUntil(std::min(t_seq, gyro_end));
    const cv::Mat gray = readSequenceImage(sequence, k);
    if (writeGroundTruthPose(sequence, k, stamp, topics, &bag)) ++summary.poses;
    info.header.stamp = stamp;
    info.header.seq = static_cast<uint32_t>(k);
    writeImage(gray, info, options, &bag);
    ++summary.images;
  }
  gyro.writeUntil(gyro_end);
  bag.close();
  return summary;
}

BagContents readSequenceBag(const std::string& bag_path, const BagTopics& topics) {
  rosbag::Bag bag;
  try {
    bag.open(bag_path, rosbag::bagmode::Read);
  } catch (const rosbag::BagException& e) {
    throw std::runtime_error("cannot read bag '" + bag_path + "': " + e.what());
  }
  BagContents contents;
  std::map<ros::Time, sensor_msgs::CameraInfoConstPtr> infos;
  std::vector<sensor_msgs::ImageConstPtr> images;
  std::vector<sensor_msgs::CompressedImageConstPtr> compressed;
  const std::string compressed_topic = topics.image + "/compressed";
  rosbag::View view(bag, rosbag::TopicQuery({topics.image, compressed_topic, topics.camera_info, topics.gyro,
                                             topics.ground_truth, "/tf_static"}));
  for (const rosbag::MessageInstance& m : view) {
    if (m.getTopic() == topics.image) {
      if (auto p = m.instantiate<sensor_msgs::Image>()) images.push_back(p);
    } else if (m.getTopic() == compressed_topic) {
      if (auto p = m.instantiate<sensor_msgs::CompressedImage>()) compressed.push_back(p);
    } else if (m.getTopic() == topics.camera_info) {
      if (auto p = m.instantiate<sensor_msgs::CameraInfo>()) infos[p->header.stamp] = p;
    } else if (m.getTopic() == topics.gyro) {
      if (auto p = m.instantiate<sensor_msgs::Imu>()) contents.gyro.push_back(p);
    } else if (m.getTopic() == topics.ground_truth) {
      if (auto p = m.instantiate<geometry_msgs::PoseStamped>()) contents.poses.push_back(p);
    } else if (m.getTopic() == "/tf_static") {
      if (auto p = m.instantiate<tf2_msgs::TFMessage>())
        contents.static_transforms.insert(contents.static_transforms.end(), p->transforms.begin(), p->transforms.end());
    }
  }
  bag.close();
  for (const auto& image : images) {
    auto it = infos.find(image->header.stamp);
    if (it != infos.end()) contents.frames.push_back({image, nullptr, it->second});
  }
  if (!images.empty() && !compressed.empty())
    throw std::runtime_error("bag '" + bag_path + "' has images on both " + topics.image + " and " + compressed_topic);
  for (const auto& image : compressed) {
    auto it = infos.find(image->header.stamp);
    if (it != infos.end()) contents.frames.push_back({nullptr, image, it->second});
  }
  if (contents.frames.empty()) {
    throw std::runtime_error("bag '" + bag_path + "' has no images on " + topics.image + " (or " + compressed_topic +
                             ") with a camera_info on " + topics.camera_info);
  }
  return contents;
}

namespace {

/// Ground truth lookups over a BagContents.
class Truth {
 public:
  explicit Truth(const BagContents& c) {
    for (const auto& p : c.poses) poses_[p->header.stamp.toSec()] = conv::fromMsg(p->pose.orientation).toRotationMatrix();
    for (const auto& g : c.gyro) {
      gyro_.emplace_back(g->header.stamp.toSec(),
                         Eigen::Vector3d(g->angular_velocity.x, g->angular_velocity.y, g->angular_velocity.z));
    }
    std::sort(gyro_.begin(), gyro_.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    // Rotation of the camera in the gyro frame (imu <- camera); the gyro in camera axes is R^T w.
    for (const auto& t : c.static_transforms) {
      if (!c.frames.empty() && t.child_frame_id == c.frames.front().info->header.frame_id) {
        camera_from_gyro_ = conv::fromMsg(t.transform.rotation).toRotationMatrix().transpose();
      }
    }
  }
  bool hasGyro() const { return gyro_.size() >= 2; }
  bool hasPoses() const { return !poses_.empty(); }
  /// The rotation IMU <- camera of /tf_static (identity without one).
  Eigen::Matrix3d imuFromCamera() const { return camera_from_gyro_.transpose(); }
  std::vector<GyroSample> gyroSamples() const {
    std::vector<GyroSample> out(gyro_.size());
    for (size_t i = 0; i < gyro_.size(); ++i) out[i] = GyroSample{gyro_[i].first, gyro_[i].second};
    return out;
  }
  /// Replaces the gyro by `samples` (sorted, IMU frame).
  void setGyro(const std::vector<GyroSample>& samples) {
    gyro_.clear();
    for (const GyroSample& s : samples) gyro_.emplace_back(s.stamp, s.angular_velocity);
  }

  bool pose(double t, Eigen::Matrix3d* r) const {
    auto it = poses_.lower_bound(t - 1e-3);
    if (it == poses_.end() || std::abs(it->first - t) > 1e-3) return false;
    *r = it->second;
    return true;
  }

  /// Gyro rate at t, linearly interpolated, in camera axes.
  Eigen::Vector3d rateAt(double t) const {
    auto it = std::lower_bound(gyro_.begin(), gyro_.end(), t, [](const auto& a, double v) { return a.first < v; });
    if (it == gyro_.begin()) return camera_from_gyro_ * it->second;
    if (it == gyro_.end()) return camera_from_gyro_ * gyro_.back().second;
    const auto& b = *it;
    const auto& a = *(it - 1);
    const double w = (t - a.first) / std::max(b.first - a.first, 1e-12);
    return camera_from_gyro_ * ((1.0 - w) * a.second + w * b.second);
  }

  /// Rotation R_{t0}^T R_{t1} from the gyro (trapezoid per sample interval) and the mean rate.
  bool gyroRotation(double t0, double t1, Eigen::Matrix3d* r, Eigen::Vector3d* mean_rate) const {
    if (!hasGyro() || t0 < gyro_.front().first || t1 > gyro_.back().first || !(t1 > t0)) return false;
    std::vector<double> times{t0};
    for (const auto& g : gyro_)
      if (g.first > t0 && g.first < t1) times.push_back(g.first);
    times.push_back(t1);
    Eigen::Matrix3d acc = Eigen::Matrix3d::Identity();
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (size_t i = 0; i + 1 < times.size(); ++i) {
      const double dt = times[i + 1] - times[i];
      const Eigen::Vector3d w = 0.5 * (rateAt(times[i]) + rateAt(times[i + 1]));
      acc = acc * so3Exp(w * dt);
      sum += w * dt;
    }
    *r = acc;
    *mean_rate = sum / (t1 - t0);
    return true;
  }

 private:
  std::map<double, Eigen::Matrix3d> poses_;
  std::vector<std::pair<double, Eigen::Vector3d>> gyro_;
  Eigen::Matrix3d camera_from_gyro_ = Eigen::Matrix3d::Identity();
};

/// The gyro of `truth` aligned with the estimates (offset and bias removed, the /tf_static rotation
/// kept), as evaluate aligns a gyro reference; false (and the gyro untouched) when it cannot be.
bool alignGyro(const std::vector<visual_gyro::RotationEstimate>& estimates, Truth* truth, ImuAlignment* alignment) {
  std::vector<VisualRate> rates;
  for (const auto& e : estimates) {
    VisualRate rate;
    rate.start = e.previous_stamp.toSec();
    rate.end = rate.start + e.dt;
    rate.valid = e.valid && e.dt > 0.0;
    rate.rate = Eigen::Vector3d(e.angular_velocity.x, e.angular_velocity.y, e.angular_velocity.z);
    for (int i = 0; i < 9; ++i) rate.covariance(i / 3, i % 3) = e.angular_velocity_covariance[i];
    rates.push_back(rate);
  }
  ImuAlignmentSettings settings;
  settings.rotation_known = true;
  settings.known_imu_from_camera = truth->imuFromCamera();
  try {
    *alignment = alignImu(rates, truth->gyroSamples(), settings);
  } catch (const ImuAlignmentError& e) {
    std::fprintf(stderr, "evaluateOutputs: the gyro reference is scored as recorded: %s\n", e.what());
    return false;
  }
  truth->setGyro(alignedGyro(truth->gyroSamples(), *alignment));
  return true;
}

}  // namespace

OutputSummary evaluateOutputs(const std::vector<visual_gyro::RotationEstimate>& estimates, int imu_count,
                              const BagContents& truth_bag, const std::string& dataset) {
  OutputSummary s;
  s.dataset = dataset;
  s.imu_published = imu_count;
  Truth truth(truth_bag);
  if (truth.hasGyro() && !truth.hasPoses()) s.gyro_aligned = alignGyro(estimates, &truth, &s.gyro_alignment);
  // Scored as evaluate scores: an invalid estimate is the identity (metrics::scoreFrame).
  metrics::AccuracyAccumulator accuracy;
  double detect = 0, describe = 0, match = 0, align = 0, estimate = 0, total = 0, latency = 0;
  for (const auto& e : estimates) {
    if (s.method.empty()) s.method = e.method;
    if (s.backend.empty()) s.backend = e.backend;
    detect += e.detect_ms;
    describe += e.describe_ms;
    match += e.match_ms;
    align += e.align_ms;
    estimate += e.estimate_ms;
    total += e.total_ms;
    latency += e.latency_ms;

    const double t0 = e.previous_stamp.toSec();
    const double t1 = t0 + e.dt;  // the current image's stamp, also when outputs use the midpoint
    metrics::FrameEstimate frame;
    frame.valid = e.valid;
    frame.rotation = conv::fromMsg(e.rotation).toRotationMatrix();
    frame.dt = e.dt;
    metrics::FrameTruth reference;
    Eigen::Matrix3d r0, r1, r_gyro;
    Eigen::Vector3d mean_rate;
    // The poses are the reference for the rotation when the bag has them; the gyro for the rate.
    if (truth.pose(t0, &r0) && truth.pose(t1, &r1)) {
      reference.has_rotation = reference.from_poses = true;
      reference.rotation = r0.transpose() * r1;
    }
    if (truth.gyroRotation(t0, t1, &r_gyro, &mean_rate)) {
      reference.has_rate = true;
      reference.rate = mean_rate;
      if (!reference.has_rotation) {
        reference.has_rotation = true;
        reference.rotation = r_gyro;
      }
    }
    accuracy.add(e.valid, metrics::scoreFrame(frame, reference), reference);
  }
  s.accuracy = accuracy.summary();
  if (!estimates.empty()) {
    const double n = static_cast<double>(estimates.size());
    s.detect_ms = detect / n;
    s.describe_ms = describe / n;
    s.match_ms = match / n;
    s.align_ms = align / n;
    s.estimate_ms = estimate / n;
    s.total_ms = total / n;
    s.latency_ms = latency / n;
  }
  return s;
}

std::string OutputSummary::json() const {
  JsonObject times;
  times.add("detect", detect_ms).add("describe", describe_ms).add("match", match_ms).add("align", align_ms).add("estimate", estimate_ms)
      .add("total", total_ms);
  JsonObject j;
  j.add("dataset", dataset).add("method", method);
  metrics::addAccuracyFields(accuracy, &j);
  j.add("ms_per_frame", times)
      .add("imu_published", imu_published)
      .add("latency_ms", latency_ms)
      .add("backend", backend)
      .add("source", "ros");
  eval::addAlignmentSummary(gyro_aligned ? &gyro_alignment : nullptr, &j);
  j.add("gyro_aligned", gyro_aligned);
  return j.str();
}

std::string OutputSummary::text() const {
  std::ostringstream t;
  auto num = [](double v, int p = 3) {
    if (!std::isfinite(v)) return std::string("n/a");
    std::ostringstream out;
    out << std::fixed << std::setprecision(p) << v;
    return out.str();
  };
  const metrics::AccuracySummary& a = accuracy;
  t << "dataset " << dataset << ", method " << method << ", backend " << backend << " (through ROS)\n"
    << "  RotationEstimate messages: " << a.frames << " (" << a.frames - a.invalid << " valid, " << a.with_truth
    << " with ground truth); Imu messages: " << imu_published << "\n"
    << "  rotation error per frame: RMSE " << num(a.rot_rmse_deg) << " deg, max " << num(a.rot_max_deg) << " deg\n"
    << "  yaw error per frame:      RMSE " << num(a.yaw_rmse_deg) << " deg, max " << num(a.yaw_max_deg) << " deg\n"
    << "  mean rate " << num(a.mean_rate_dps, 2) << " deg/s, rate RMSE vs gyro " << num(a.rate_rmse_dps) << " deg/s"
    << (gyro_aligned ? " (gyro aligned: bias and clock offset removed)" : "") << "\n"
    << "  time per frame: detect " << num(detect_ms, 2) << " ms, describe " << num(describe_ms, 2) << " ms, match "
    << num(match_ms, 2) << " ms, align " << num(align_ms, 2) << " ms, estimate " << num(estimate_ms, 2) << " ms, total " << num(total_ms, 2)
    << " ms; latency image callback -> publish " << num(latency_ms, 2) << " ms";
  return t.str();
}

}  // namespace bag_tools
}  // namespace visual_gyro
