// libFuzzer target: the dataset readers (loadSequence) on folders whose text files come from the
// fuzzer: KITTI (calib.txt, times.txt, poses.txt) or EuRoC (cam0/data.csv, cam0/sensor.yaml,
// imu0/data.csv, state_groundtruth_estimate0/data.csv). Bad files must give std::runtime_error
// naming the file, never a crash, a hang or a sanitizer report.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

#include "visual_gyro/sequence.h"

namespace fs = std::filesystem;

namespace {

fs::path root() {
  static const fs::path path = [] {
    const fs::path p = fs::temp_directory_path() / ("visual_gyro_fuzz_sequence_" + std::to_string(getpid()));
    fs::create_directories(p);
    return p;
  }();
  return path;
}

void write(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

/// Two small PNGs under `folder`, with the names the layouts expect.
void images(const fs::path& folder, const std::vector<std::string>& names) {
  const cv::Mat img(12, 16, CV_8UC1, cv::Scalar(100));
  for (const std::string& n : names) {
    if (!fs::exists(folder / n)) {
      fs::create_directories(folder);
      cv::imwrite((folder / n).string(), img);
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  // Byte 0 picks the layout; the rest is split into files at 0xFF bytes.
  std::vector<std::string> parts(1);
  for (size_t i = 1; i < size; ++i) {
    if (data[i] == 0xFF) parts.emplace_back();
    else parts.back() += static_cast<char>(data[i]);
  }
  parts.resize(4);
  const fs::path dir = root() / "case";
  fs::remove_all(dir);
  if (data[0] % 2 == 0) {
    images(dir / "image_l", {"000000.png", "000001.png"});
    write(dir / "calib.txt", parts[0]);
    if (!parts[1].empty()) write(dir / "times.txt", parts[1]);
    if (!parts[2].empty()) write(dir / "poses.txt", parts[2]);
  } else {
    images(dir / "cam0" / "data", {"1000.png", "2000.png"});
    write(dir / "cam0" / "data.csv", parts[0]);
    write(dir / "cam0" / "sensor.yaml", parts[1]);
    if (!parts[2].empty()) write(dir / "imu0" / "data.csv", parts[2]);
    if (!parts[3].empty()) write(dir / "state_groundtruth_estimate0" / "data.csv", parts[3]);
  }
  try {
    const visual_gyro::Sequence seq = visual_gyro::loadSequence(dir.string());
    // What loads must be consistent.
    if (seq.stamps.size() != seq.image_paths.size()) __builtin_trap();
    Eigen::Matrix3d r;
    Eigen::Vector3d w;
    for (size_t k = 1; k < seq.image_paths.size(); ++k) {
      seq.trueRotation(k, &r);
      seq.trueAngularVelocity(k, &w);
    }
  } catch (const std::runtime_error&) {
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
