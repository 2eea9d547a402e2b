// Soak of the visual_gyro node: replays a sequence forwards and backwards at 30 Hz (camera +
// camera_info) for ~minutes, samples the node's resident memory, open descriptors and threads
// every 10 s (from /proc, the node's pid asked over its XML-RPC API), and measures the latency
// from publishing an image to receiving its ~orientation. Prints one line per sample and, last,
// one JSON line (also written to ~result_file): frames_in, estimates_out, rss_mb_start (after the
// warm-up: the first sample), rss_mb_end, fds_start, fds_end, latency_ms_p99 and more. As a test
// (~assert true) it requires, after the warm-up, RSS growth <= 2 MB, no new descriptors, and >= 95 %
// of the frames answered.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <dirent.h>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <geometry_msgs/PoseStamped.h>
#include <image_transport/image_transport.h>
#include <opencv2/imgcodecs.hpp>
#include <ros/network.h>
#include <ros/ros.h>
#include <visual_gyro/RotationEstimate.h>
#include <xmlrpcpp/XmlRpcClient.h>

#include "ros_conversions.h"
#include "test_support.h"
#include "visual_gyro/renderer.h"
#include "visual_gyro/sequence.h"

namespace {

namespace conv = visual_gyro::ros_conversions;

struct ProcessSample {
  double rss_mb = 0.0;
  int fds = 0, threads = 0;
};

/// The pid of a ROS node, asked over its XML-RPC API (getPid); -1 when it cannot be reached.
int nodePid(const std::string& node) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, false)) return -1;
  std::string host, path;
  uint32_t port = 0;
  if (!ros::network::splitURI(static_cast<std::string>(payload), host, port)) return -1;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  XmlRpc::XmlRpcValue pid_args, pid_result;
  pid_args[0] = ros::this_node::getName();
  if (!client.execute("getPid", pid_args, pid_result) || pid_result.getType() != XmlRpc::XmlRpcValue::TypeArray ||
      pid_result.size() < 3) {
    return -1;
  }
  return static_cast<int>(pid_result[2]);
}

ProcessSample sampleProcess(int pid) {
  ProcessSample s;
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string key;
  while (status >> key) {
    if (key == "VmRSS:") {
      double kb = 0;
      status >> kb;
      s.rss_mb = kb / 1024.0;
    } else if (key == "Threads:") {
      status >> s.threads;
    }
    std::string rest;
    std::getline(status, rest);
  }
  if (DIR* dir = opendir(("/proc/" + std::to_string(pid) + "/fd").c_str())) {
    while (dirent* e = readdir(dir))
      if (e->d_name[0] != '.') ++s.fds;
    closedir(dir);
  }
  return s;
}

/// The frames to replay (gray) and their camera; the shared kitti_turn when present, else rendered.
void loadFrames(std::vector<cv::Mat>* frames, visual_gyro::CameraModel* camera, std::string* source) {
  std::string why;
  const std::string folder = visual_gyro::test::sharedSequence("kitti_turn", &why);
  if (!folder.empty()) {
    const visual_gyro::Sequence seq = visual_gyro::loadSequence(folder);
    for (const std::string& path : seq.image_paths) frames->push_back(cv::imread(path, cv::IMREAD_GRAYSCALE));
    *camera = seq.camera;
    *source = folder;
    return;
  }
  visual_gyro::RenderSettings s;
  s.preset = visual_gyro::RenderPreset::kHandheld;
  s.setCentredCamera(640, 480, 500.0);
  for (int k = 0; k < 40; ++k) {
    frames->push_back(visual_gyro::renderView(
        s, Eigen::AngleAxisd(0.5 * k * M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix(),
        Eigen::Vector3d::Zero()));
  }
  *camera = visual_gyro::CameraModel(s.fx, s.fy, s.cx, s.cy, s.width, s.height);
  *source = "rendered handheld turn (" + why + ")";
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t i = std::min(v.size() - 1, static_cast<size_t>(p * (v.size() - 1) + 0.5));
  return v[i];
}

TEST(Soak, ReplayKeepsMemoryDescriptorsAndAnswers) {
  ros::NodeHandle nh, pnh("~");
  double minutes = 1.0, rate_hz = 30.0;
  std::string node = "/visual_gyro", result_file;
  bool check = true;
  pnh.param("minutes", minutes, minutes);
  pnh.param("rate", rate_hz, rate_hz);
  pnh.param("node", node, node);
  pnh.param("result_file", result_file, result_file);
  pnh.param("assert", check, check);

  std::vector<cv::Mat> frames;
  visual_gyro::CameraModel camera;
  std::string source;
  loadFrames(&frames, &camera, &source);
  ASSERT_GE(frames.size(), 3u);
  std::printf("[soak] %.1f min at %.0f Hz, %zu frames forwards and backwards from %s\n", minutes, rate_hz,
              frames.size(), source.c_str());

  image_transport::ImageTransport it(nh);
  image_transport::CameraPublisher pub = it.advertiseCamera("/soak_camera/image_raw", 5);
  std::mutex mutex;
  std::map<double, ros::WallTime> sent;  // stamp -> wall time of publishing
  std::vector<double> latencies_ms;
  std::atomic<uint64_t> answered{0}, estimates{0};
  ros::Subscriber orientation_sub = nh.subscribe<geometry_msgs::PoseStamped>(
      node + "/orientation", 100, [&](const geometry_msgs::PoseStampedConstPtr& m) {
        const ros::WallTime now = ros::WallTime::now();
        std::lock_guard<std::mutex> lock(mutex);
        auto it_sent = sent.find(m->header.stamp.toSec());
        if (it_sent == sent.end()) return;
        latencies_ms.push_back((now - it_sent->second).toSec() * 1e3);
        sent.erase(sent.begin(), std::next(it_sent));
        ++answered;
      });
  ros::Subscriber rotation_sub = nh.subscribe<visual_gyro::RotationEstimate>(
      node + "/rotation", 100, [&](const visual_gyro::RotationEstimateConstPtr&) { ++estimates; });
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const ros::WallTime wait_end = ros::WallTime::now() + ros::WallDuration(20.0);
  while (pub.getNumSubscribers() == 0 && ros::WallTime::now() < wait_end) ros::WallDuration(0.05).sleep();
  ASSERT_GT(pub.getNumSubscribers(), 0u) << "the node never subscribed to the camera";
  const int pid = nodePid(node);
  ASSERT_GT(pid, 0) << "no pid for " << node;

  // Messages made once: the replay measures the node, not this publisher.
  std::vector<sensor_msgs::Image> messages;
  for (const cv::Mat& f : frames) {
    sensor_msgs::Image m;
    m.height = f.rows;
    m.width = f.cols;
    m.encoding = "mono8";
    m.step = f.cols;
    m.header.frame_id = "soak_camera_optical";
    m.data.assign(f.data, f.data + f.total());
    messages.push_back(m);
  }
  sensor_msgs::CameraInfo info = conv::cameraInfoFromModel(camera);
  info.header.frame_id = "soak_camera_optical";

  // Forwards then backwards without repeating the end frames (a repeat is a frozen camera).
  std::vector<size_t> order;
  for (size_t k = 0; k < frames.size(); ++k) order.push_back(k);
  for (size_t k = frames.size() - 2; k >= 1; --k) order.push_back(k);

  const double duration = minutes * 60.0;
  const ros::WallTime start = ros::WallTime::now();
  ros::WallTime next_sample = start;
  std::vector<ProcessSample> samples;
  uint64_t frames_in = 0;
  const double t0 = 1000.0;
  ros::WallRate rate(rate_hz);
  for (size_t i = 0; ros::ok() && (ros::WallTime::now() - start).toSec() < duration; ++i) {
    if (ros::WallTime::now() >= next_sample) {
      const ProcessSample s = sampleProcess(pid);
      samples.push_back(s);
      std::lock_guard<std::mutex> lock(mutex);
      std::printf("[soak] %5.0f s: rss %.1f MB, fds %d, threads %d, frames %llu, answered %llu, p99 %.1f ms\n",
                  (ros::WallTime::now() - start).toSec(), s.rss_mb, s.fds, s.threads,
                  static_cast<unsigned long long>(frames_in), static_cast<unsigned long long>(answered.load()),
                  percentile(latencies_ms, 0.99));
      std::fflush(stdout);
      next_sample += ros::WallDuration(10.0);
    }
    sensor_msgs::Image image = messages[order[i % order.size()]];
    image.header.stamp.fromSec(t0 + i / rate_hz);
    info.header.stamp = image.header.stamp;
    {
      std::lock_guard<std::mutex> lock(mutex);
      sent[image.header.stamp.toSec()] = ros::WallTime::now();
    }
    pub.publish(image, info);
    ++frames_in;
    rate.sleep();
  }
  ros::WallDuration(1.0).sleep();  // the last answers
  samples.push_back(sampleProcess(pid));
  spinner.stop();

  // The first sample is taken before any frame: the warm-up ends with the second (10 s in).
  const ProcessSample launch = samples.front();
  const ProcessSample warm = samples.size() > 2 ? samples[1] : samples.front();
  const ProcessSample end = samples.back();
  double p99 = 0.0;
  {
    std::lock_guard<std::mutex> lock(mutex);
    p99 = percentile(latencies_ms, 0.99);
  }
  const double answered_fraction = frames_in > 0 ? static_cast<double>(answered.load()) / frames_in : 0.0;
  char json[1024];
  std::snprintf(json, sizeof(json),
                "{\"frames_in\": %llu, \"estimates_out\": %llu, \"rss_mb_start\": %.1f, \"rss_mb_end\": %.1f, "
                "\"fds_start\": %d, \"fds_end\": %d, \"latency_ms_p99\": %.2f, \"answered_fraction\": %.4f, "
                "\"threads_start\": %d, \"threads_end\": %d, \"rss_mb_launch\": %.1f, \"minutes\": %.2f, "
                "\"rate_hz\": %.1f}",
                static_cast<unsigned long long>(frames_in), static_cast<unsigned long long>(estimates.load()),
                warm.rss_mb, end.rss_mb, warm.fds, end.fds, p99, answered_fraction, warm.threads, end.threads,
                launch.rss_mb, minutes, rate_hz);
  std::printf("%s\n", json);
  if (!result_file.empty()) std::ofstream(result_file) << json << "\n";
  if (!check) return;
  EXPECT_LE(end.rss_mb - warm.rss_mb, 2.0) << "resident memory grew after the warm-up";
  EXPECT_LE(end.fds, warm.fds) << "descriptors were opened and not closed";
  EXPECT_GE(answered_fraction, 0.95) << "frames went unanswered";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "soak");
  const int result = RUN_ALL_TESTS();
  ros::shutdown();  // roscpp's threads stop before static destruction frees what they read
  return result;
}
