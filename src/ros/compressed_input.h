// Compressed camera images (sensor_msgs/CompressedImage, JPEG or PNG) without image_transport's
// compressed plugin: encoding for bags and decoding for the nodelet, with OpenCV.
#pragma once

#include <string>

#include <opencv2/core.hpp>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>

namespace visual_gyro {
namespace compressed_input {

/// Compression formats make_bag writes.
enum class Compression { kNone, kJpeg, kPng };

/// Parses "jpeg" (or "jpg"), "png" or "none"; false for anything else.
bool parseCompression(const std::string& name, Compression* compression);

/// JPEG quality make_bag uses (that of image_transport's compressed plugin by default) [0..100].
constexpr int kDefaultJpegQuality = 90;

/// Encodes a CV_8UC1 image as a CompressedImage (header left empty). `format` is written the way
/// image_transport's compressed plugin writes it for mono8 ("mono8; jpeg compressed ",
/// "mono8; png compressed "). Throws std::invalid_argument for another image type or kNone.
sensor_msgs::CompressedImage encodeGray(const cv::Mat& gray, Compression compression,
                                        int jpeg_quality = kDefaultJpegQuality);

/// Decodes a CompressedImage (JPEG or PNG, any of the formats image_transport's plugin writes)
/// into an Image with the same header: 1 channel 8 bit -> mono8, 16 bit -> mono16, 3 channels ->
/// bgr8, 4 -> bgra8. Throws std::invalid_argument when the data cannot be decoded (with the
/// message's format in the text).
sensor_msgs::ImagePtr decode(const sensor_msgs::CompressedImage& message);

}  // namespace compressed_input
}  // namespace visual_gyro
