#include "compressed_input.h"

#include <stdexcept>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <sensor_msgs/image_encodings.h>

namespace visual_gyro {
namespace compressed_input {

bool parseCompression(const std::string& name, Compression* compression) {
  if (name == "jpeg" || name == "jpg") *compression = Compression::kJpeg;
  else if (name == "png") *compression = Compression::kPng;
  else if (name == "none") *compression = Compression::kNone;
  else return false;
  return true;
}

sensor_msgs::CompressedImage encodeGray(const cv::Mat& gray, Compression compression, int jpeg_quality) {
  if (gray.type() != CV_8UC1 || gray.empty()) throw std::invalid_argument("encodeGray needs a non-empty CV_8UC1 image");
  sensor_msgs::CompressedImage out;
  std::vector<int> params;
  std::string extension;
  if (compression == Compression::kJpeg) {
    extension = ".jpg";
    params = {cv::IMWRITE_JPEG_QUALITY, jpeg_quality};
    out.format = "mono8; jpeg compressed ";
  } else if (compression == Compression::kPng) {
    extension = ".png";
    out.format = "mono8; png compressed ";
  } else {
    throw std::invalid_argument("encodeGray: no compression format given");
  }
  if (!cv::imencode(extension, gray, out.data, params))
    throw std::invalid_argument("OpenCV could not encode the image as " + extension);
  return out;
}

sensor_msgs::ImagePtr decode(const sensor_msgs::CompressedImage& message) {
  namespace enc = sensor_msgs::image_encodings;
  if (message.data.empty())
    throw std::invalid_argument("compressed image (format '" + message.format + "') has no data");
  cv::Mat decoded;
  try {
    decoded = cv::imdecode(cv::Mat(1, static_cast<int>(message.data.size()), CV_8UC1,
                                   const_cast<uint8_t*>(message.data.data())),
                           cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    throw std::invalid_argument("cannot decode compressed image (format '" + message.format + "'): " + e.what());
  }
  if (decoded.empty())
    throw std::invalid_argument("cannot decode compressed image (format '" + message.format +
                                "'): not a JPEG or PNG OpenCV can read");
  std::string encoding;
  switch (decoded.type()) {
    case CV_8UC1: encoding = enc::MONO8; break;
    case CV_16UC1: encoding = enc::MONO16; break;
    case CV_8UC3: encoding = enc::BGR8; break;
    case CV_8UC4: encoding = enc::BGRA8; break;
    default:
      throw std::invalid_argument("compressed image (format '" + message.format + "') decodes to an unsupported "
                                  "pixel type (" + std::to_string(decoded.channels()) + " channels, depth " +
                                  std::to_string(decoded.depth()) + ")");
  }
  sensor_msgs::ImagePtr image(new sensor_msgs::Image);
  image->header = message.header;
  image->height = static_cast<uint32_t>(decoded.rows);
  image->width = static_cast<uint32_t>(decoded.cols);
  image->encoding = encoding;
  image->is_bigendian = 0;
  const size_t row_bytes = decoded.cols * decoded.elemSize();
  image->step = static_cast<uint32_t>(row_bytes);
  image->data.resize(row_bytes * decoded.rows);
  for (int r = 0; r < decoded.rows; ++r)
    std::copy(decoded.ptr<uint8_t>(r), decoded.ptr<uint8_t>(r) + row_bytes, &image->data[r * row_bytes]);
  return image;
}

}  // namespace compressed_input
}  // namespace visual_gyro
