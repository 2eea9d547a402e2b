#include "ros_conversions.h"

#include <cmath>
#include <stdexcept>

#include <opencv2/imgproc.hpp>
#include <sensor_msgs/distortion_models.h>

namespace visual_gyro {
namespace ros_conversions {

bool cameraModelFromInfo(const sensor_msgs::CameraInfo& info, CameraModel* model, std::string* why) {
  double fx = info.K[0], fy = info.K[4], cx = info.K[2], cy = info.K[5];
  if (!(fx > 0.0) || !(fy > 0.0) || !std::isfinite(fx) || !std::isfinite(fy)) {
    *why = "camera_info has no usable calibration (K[0] = " + std::to_string(fx) +
           ", K[4] = " + std::to_string(fy) +
           "); calibrate the camera or set ~use_camera_info false and give ~fx, ~fy, ~cx, ~cy";
    return false;
  }
  int width = static_cast<int>(info.width), height = static_cast<int>(info.height);
  // ROI and binning describe how the published image relates to the calibrated full sensor
  // (REP 104): shift the principal point by the ROI offset, then scale by the binning.
  const bool has_roi = info.roi.width > 0 && info.roi.height > 0 &&
                       (info.roi.width != info.width || info.roi.height != info.height ||
                        info.roi.x_offset != 0 || info.roi.y_offset != 0);
  if (has_roi) {
    cx -= info.roi.x_offset;
    cy -= info.roi.y_offset;
    width = static_cast<int>(info.roi.width);
    height = static_cast<int>(info.roi.height);
  }
  const double bx = info.binning_x > 1 ? info.binning_x : 1.0;
  const double by = info.binning_y > 1 ? info.binning_y : 1.0;
  if (bx > 1.0 || by > 1.0) {
    fx /= bx;
    cx = (cx + 0.5) / bx - 0.5;
    fy /= by;
    cy = (cy + 0.5) / by - 0.5;
    width = static_cast<int>(width / bx);
    height = static_cast<int>(height / by);
    if (width < 1 || height < 1) {
      *why = "camera_info binning " + std::to_string(info.binning_x) + "x" + std::to_string(info.binning_y) +
             " leaves a " + std::to_string(width) + "x" + std::to_string(height) + " image of the " +
             std::to_string(has_roi ? info.roi.width : info.width) + "x" +
             std::to_string(has_roi ? info.roi.height : info.height) + " calibrated one";
      return false;
    }
  }

  std::vector<double> d(info.D.begin(), info.D.end());
  bool all_zero = true;
  for (double v : d) all_zero = all_zero && v == 0.0;
  DistortionModel dm = DistortionModel::kNone;
  const std::string& name = info.distortion_model;
  if (d.empty() || all_zero) {
    dm = DistortionModel::kNone;
    d.clear();
  } else if (name == sensor_msgs::distortion_models::PLUMB_BOB) {
    dm = DistortionModel::kPlumbBob;
  } else if (name == sensor_msgs::distortion_models::RATIONAL_POLYNOMIAL) {
    // k1 k2 p1 p2 k3 k4 k5 k6. Some drivers append OpenCV's thin-prism and tilt terms (s1..s4,
    // tau_x, tau_y), which the model lacks: a bearing without them would be silently wrong.
    for (size_t i = 8; i < d.size(); ++i) {
      if (d[i] != 0.0) {
        *why = "camera_info distortion model rational_polynomial has a non-zero coefficient D[" + std::to_string(i) +
               "] beyond k1 k2 p1 p2 k3 k4 k5 k6 (thin-prism or tilt terms are not supported)";
        return false;
      }
    }
    d.resize(8, 0.0);
    dm = DistortionModel::kPlumbBob;
  } else if (!parseDistortionModel(name, &dm)) {
    *why = "camera_info distortion model '" + name +
           "' is not supported (plumb_bob, rational_polynomial, equidistant)";
    return false;
  }
  *model = CameraModel(fx, fy, cx, cy, width, height, dm, d);
  return true;
}

sensor_msgs::CameraInfo cameraInfoFromModel(const CameraModel& model) {
  sensor_msgs::CameraInfo info;
  info.width = static_cast<uint32_t>(model.width());
  info.height = static_cast<uint32_t>(model.height());
  info.K = {model.fx(), 0.0, model.cx(), 0.0, model.fy(), model.cy(), 0.0, 0.0, 1.0};
  info.R = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  info.P = {model.fx(), 0.0, model.cx(), 0.0, 0.0, model.fy(), model.cy(), 0.0, 0.0, 0.0, 1.0, 0.0};
  switch (model.distortionModel()) {
    case DistortionModel::kEquidistant:
      info.distortion_model = sensor_msgs::distortion_models::EQUIDISTANT;
      info.D = model.distortion();
      break;
    case DistortionModel::kPlumbBob:
      info.D = model.distortion();
      // ROS tools expect k1 k2 p1 p2 k3, and the rational model's eight under its own name.
      info.distortion_model = info.D.size() == 8 ? sensor_msgs::distortion_models::RATIONAL_POLYNOMIAL
                                                 : sensor_msgs::distortion_models::PLUMB_BOB;
      if (info.D.size() < 5) info.D.resize(5, 0.0);
      break;
    default:
      info.distortion_model = sensor_msgs::distortion_models::PLUMB_BOB;
      info.D.assign(5, 0.0);
      break;
  }
  return info;
}

namespace {

// How a pixel encoding becomes grey: used as it is, the mono16 scaling, or a cv::cvtColor code.
constexpr int kAsIs = -1;
constexpr int kMono16 = -2;

struct EncodingConversion {
  const char* encoding;
  int type;            ///< cv::Mat type of the message's pixels
  int to_gray;         ///< kAsIs, kMono16 or a cv::ColorConversionCodes value
  int width_multiple;  ///< the width must be a multiple of this (pixel pairs of YUV 4:2:2)
  int min_side;        ///< smallest width and height the conversion reads
};

// ROS names a Bayer mosaic by its top-left 2 x 2 cell, OpenCV by the cell one row and one column
// further in (cv_bridge's mapping): bayer_rggb8 is OpenCV's BayerBG. ROS's yuv422 is UYVY byte
// order; yuv422_yuy2 (newer drivers, e.g. usb_cam) is YUYV. Grey is their Y (luma) samples.
constexpr EncodingConversion kConversions[] = {
    {"mono8", CV_8UC1, kAsIs, 1, 1},
    {"8UC1", CV_8UC1, kAsIs, 1, 1},
    {"mono16", CV_16UC1, kMono16, 1, 1},
    {"bgr8", CV_8UC3, cv::COLOR_BGR2GRAY, 1, 1},
    {"rgb8", CV_8UC3, cv::COLOR_RGB2GRAY, 1, 1},
    {"bgra8", CV_8UC4, cv::COLOR_BGRA2GRAY, 1, 1},
    {"rgba8", CV_8UC4, cv::COLOR_RGBA2GRAY, 1, 1},
    {"bayer_rggb8", CV_8UC1, cv::COLOR_BayerBG2GRAY, 1, 2},
    {"bayer_bggr8", CV_8UC1, cv::COLOR_BayerRG2GRAY, 1, 2},
    {"bayer_gbrg8", CV_8UC1, cv::COLOR_BayerGR2GRAY, 1, 2},
    {"bayer_grbg8", CV_8UC1, cv::COLOR_BayerGB2GRAY, 1, 2},
    {"yuv422", CV_8UC2, cv::COLOR_YUV2GRAY_UYVY, 2, 1},
    {"yuv422_yuy2", CV_8UC2, cv::COLOR_YUV2GRAY_YUY2, 2, 1},
};

const EncodingConversion* conversionOf(const std::string& encoding) {
  for (const EncodingConversion& c : kConversions) {
    if (encoding == c.encoding) return &c;
  }
  return nullptr;
}

// A mono16 frame's native byte order, scaled to 8 bits as toGray() states.
cv::Mat mono16ToGray(const sensor_msgs::Image& image, const cv::Mat& raw, int mono16_bit_depth) {
  cv::Mat host = raw;
  const bool host_big_endian = (*reinterpret_cast<const uint16_t*>("\x01\x00") != 1);
  if (static_cast<bool>(image.is_bigendian) != host_big_endian) {
    host = raw.clone();
    for (int r = 0; r < host.rows; ++r) {
      auto* p = host.ptr<uint16_t>(r);
      for (int c = 0; c < host.cols; ++c) p[c] = static_cast<uint16_t>((p[c] >> 8) | (p[c] << 8));
    }
  }
  int bits = mono16_bit_depth;
  if (bits == 0) {
    // Per frame, with no state: one saturated pixel darkens only its own frame.
    double max_value = 0.0;
    cv::minMaxLoc(host, nullptr, &max_value);
    bits = 8;
    while (bits < 16 && (1 << bits) - 1 < max_value) ++bits;
  }
  // convertTo saturates: values above the declared depth read as white.
  cv::Mat gray;
  host.convertTo(gray, CV_8U, 255.0 / ((1 << bits) - 1));
  return gray;
}

}  // namespace

std::vector<std::string> supportedEncodings() {
  std::vector<std::string> names;
  for (const EncodingConversion& c : kConversions) names.emplace_back(c.encoding);
  return names;
}

bool isSupportedEncoding(const std::string& encoding) { return conversionOf(encoding) != nullptr; }

cv::Mat toGray(const sensor_msgs::Image& image, int mono16_bit_depth) {
  const std::string& e = image.encoding;
  if (mono16_bit_depth != 0 && (mono16_bit_depth < 8 || mono16_bit_depth > 16)) {
    throw std::invalid_argument("mono16 bit depth must be 0 (per frame) or 8..16, got " +
                                std::to_string(mono16_bit_depth));
  }
  const EncodingConversion* conversion = conversionOf(e);
  if (conversion == nullptr) {
    std::string names;
    for (const std::string& name : supportedEncodings()) names += (names.empty() ? "" : ", ") + name;
    throw std::invalid_argument("unsupported image encoding '" + e + "' (" + names + " are)");
  }
  const int type = conversion->type;
  const size_t row_bytes = static_cast<size_t>(image.width) * CV_ELEM_SIZE(type);
  // cv::Mat takes int sizes and a size_t step; larger claims are malformed (and would overflow).
  constexpr uint32_t kMaxSide = 1u << 20;
  const auto side = static_cast<uint32_t>(conversion->min_side);
  if (image.width < side || image.height < side || image.width > kMaxSide || image.height > kMaxSide ||
      image.width % conversion->width_multiple != 0 || image.step < row_bytes ||
      image.step % CV_ELEM_SIZE1(type) != 0 ||
      image.data.size() < static_cast<size_t>(image.step) * image.height) {
    throw std::invalid_argument("malformed image: " + std::to_string(image.width) + "x" +
                                std::to_string(image.height) + " step " +
                                std::to_string(image.step) + " with " +
                                std::to_string(image.data.size()) + " bytes of " + e);
  }
  const cv::Mat raw(static_cast<int>(image.height), static_cast<int>(image.width), type,
                    const_cast<uint8_t*>(image.data.data()), image.step);
  if (conversion->to_gray == kAsIs) return raw;
  if (conversion->to_gray == kMono16) return mono16ToGray(image, raw, mono16_bit_depth);
  cv::Mat gray;
  cv::cvtColor(raw, gray, conversion->to_gray);
  return gray;
}

geometry_msgs::Quaternion toMsg(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  geometry_msgs::Quaternion m;
  m.w = q.w();
  m.x = q.x();
  m.y = q.y();
  m.z = q.z();
  return m;
}

Eigen::Quaterniond fromMsg(const geometry_msgs::Quaternion& m) {
  Eigen::Quaterniond q(m.w, m.x, m.y, m.z);
  const double n = q.norm();
  if (!(n > 0.0) || !std::isfinite(n)) return Eigen::Quaterniond::Identity();
  return Eigen::Quaterniond(q.coeffs() / n);
}

}  // namespace ros_conversions
}  // namespace visual_gyro
