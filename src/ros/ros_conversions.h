// Conversions between ROS messages and the ROS-free core types of visual_gyro.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <geometry_msgs/Quaternion.h>
#include <opencv2/core.hpp>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include "visual_gyro/camera_model.h"

namespace visual_gyro {
namespace ros_conversions {

/// Camera model from a CameraInfo: K (fx, fy, cx, cy), size, distortion model and D, with binning and
/// ROI applied. "plumb_bob" takes 4, 5 or 8 coefficients; "rational_polynomial" takes k1 k2 p1 p2 k3
/// k4 k5 k6 (fewer are padded with zeros; terms beyond them must be zero); "equidistant" takes 4; an
/// empty or all-zero D means no distortion. Returns false with the reason in *why when the message
/// cannot be used (e.g. an uncalibrated camera with K = 0). The model is not validated beyond that:
/// call validate().
bool cameraModelFromInfo(const sensor_msgs::CameraInfo& info, CameraModel* model, std::string* why);

/// CameraInfo for a model (K, P = [K | 0], R = I, D and distortion_model as ROS names them).
sensor_msgs::CameraInfo cameraInfoFromModel(const CameraModel& model);

/// The encodings the nodelet converts to grey, in the order the docs list them: mono8, 8UC1,
/// mono16, bgr8, rgb8, bgra8, rgba8, the four 8-bit Bayer mosaics (bayer_rggb8, ...), yuv422
/// (UYVY) and yuv422_yuy2 (YUYV).
std::vector<std::string> supportedEncodings();

/// True when the encoding is one of supportedEncodings().
bool isSupportedEncoding(const std::string& encoding);

/// Converts an image of a supported encoding to CV_8UC1 (mono8 and 8UC1 are shared, not copied;
/// a Bayer mosaic is demosaiced to grey, YUV 4:2:2 gives its Y samples).
/// mono16 is scaled by 255 / (2^bits - 1): bits = mono16_bit_depth (8..16, e.g. 12 for a 12-bit
/// camera; larger values saturate), or, when it is 0, the smallest depth (>= 8) covering this
/// frame's largest value, so 12-bit cameras are not dark. No state survives a frame. Throws
/// std::invalid_argument for other encodings, a bit depth outside 0 or 8..16, or a malformed
/// image (step or size inconsistent, a 16-bit row step that is odd, a side above 2^20, a Bayer
/// mosaic under 2 x 2 pixels, a YUV 4:2:2 width that is odd).
cv::Mat toGray(const sensor_msgs::Image& image, int mono16_bit_depth);

/// Row-major copy of a 3x3 matrix into a float64[9] field.
template <typename Array>
void toRowMajor(const Eigen::Matrix3d& m, Array* out) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) (*out)[3 * r + c] = m(r, c);
}

/// geometry_msgs quaternion of an Eigen quaternion (normalised).
geometry_msgs::Quaternion toMsg(const Eigen::Quaterniond& q);
/// Eigen quaternion of a geometry_msgs quaternion (normalised; identity when it has zero norm).
Eigen::Quaterniond fromMsg(const geometry_msgs::Quaternion& q);

}  // namespace ros_conversions
}  // namespace visual_gyro
