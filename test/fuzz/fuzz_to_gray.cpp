// libFuzzer target: the ROS image conversion (toGray) with any encoding, size, step, endianness,
// bit depth and data, and the CameraInfo reading with the calibration check. Bad input must give
// std::invalid_argument (or false with a reason), never a crash, a hang or a sanitizer report.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>

#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include "ros_conversions.h"
#include "visual_gyro/camera_model.h"

namespace {

/// Reads fixed-size fields from the front of the input (zeros once it runs out).
class Reader {
 public:
  Reader(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  template <typename T>
  T get() {
    T value{};
    const size_t n = std::min(sizeof(T), size_ - offset_);
    std::memcpy(&value, data_ + offset_, n);
    offset_ += n;
    return value;
  }
  const uint8_t* rest() const { return data_ + offset_; }
  size_t restSize() const { return size_ - offset_; }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t offset_ = 0;
};

const char* const kEncodings[] = {"mono8", "8UC1", "mono16", "bgr8", "rgb8", "bgra8", "rgba8",
                                  "bayer_rggb8", "bayer_bggr8", "bayer_gbrg8", "bayer_grbg8", "yuv422",
                                  "yuv422_yuy2", "32FC1", "", "bayer_rggb16", "mono"};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Reader in(data, size);
  const uint8_t mode = in.get<uint8_t>();
  if (mode % 2 == 0) {
    sensor_msgs::Image image;
    image.encoding = kEncodings[in.get<uint8_t>() % (sizeof(kEncodings) / sizeof(kEncodings[0]))];
    image.width = in.get<uint16_t>() % 512;
    image.height = in.get<uint16_t>() % 512;
    // Mostly near the packed row size, sometimes anything (including huge claims).
    const uint32_t raw_step = in.get<uint32_t>();
    image.step = (raw_step & 1) ? raw_step : image.width * (1 + (raw_step >> 1) % 4) + (raw_step >> 8) % 8;
    image.is_bigendian = in.get<uint8_t>() & 1;
    const int bit_depth = static_cast<int8_t>(in.get<uint8_t>()) % 20;
    image.data.assign(in.rest(), in.rest() + in.restSize());
    try {
      const cv::Mat gray = visual_gyro::ros_conversions::toGray(image, bit_depth);
      if (gray.type() != CV_8UC1 || gray.cols != static_cast<int>(image.width) ||
          gray.rows != static_cast<int>(image.height)) {
        __builtin_trap();  // a "successful" conversion of the wrong shape is a bug too
      }
    } catch (const std::invalid_argument&) {
    }
  } else {
    sensor_msgs::CameraInfo info;
    info.width = in.get<uint16_t>() % 4096;
    info.height = in.get<uint16_t>() % 4096;
    for (double& k : info.K) k = in.get<double>();
    const uint8_t d_count = in.get<uint8_t>() % 10;
    for (uint8_t i = 0; i < d_count; ++i) info.D.push_back(in.get<double>());
    const char* const models[] = {"plumb_bob", "rational_polynomial", "equidistant", "", "fisheye", "weird"};
    info.distortion_model = models[in.get<uint8_t>() % 6];
    info.binning_x = in.get<uint32_t>();
    info.binning_y = in.get<uint32_t>();
    info.roi.x_offset = in.get<uint16_t>();
    info.roi.y_offset = in.get<uint16_t>();
    info.roi.width = in.get<uint16_t>();
    info.roi.height = in.get<uint16_t>();
    visual_gyro::CameraModel model;
    std::string why;
    if (visual_gyro::ros_conversions::cameraModelFromInfo(info, &model, &why)) {
      if (visual_gyro::calibrationProblem(model).empty()) {
        // A camera that passes must give finite unit bearings at the image corners.
        const Eigen::Vector3d b = model.bearing(0.0, 0.0);
        if (!(std::abs(b.norm() - 1.0) < 1e-6)) __builtin_trap();
      }
    } else if (why.empty()) {
      __builtin_trap();  // refused without a reason
    }
  }
  return 0;
}
