// ROS conversions without a master: mono16 scaling without state, Bayer and YUV 4:2:2 images,
// malformed images found by the fuzzer, CameraInfo binning that leaves no image, the
// rational_polynomial distortion model; the encodings the docs list against the conversion's.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include <sensor_msgs/distortion_models.h>
#include <sensor_msgs/image_encodings.h>

#include "ros_conversions.h"

namespace conv = visual_gyro::ros_conversions;

namespace {

sensor_msgs::Image mono16(const cv::Mat& m) {
  sensor_msgs::Image image;
  image.width = m.cols;
  image.height = m.rows;
  image.encoding = sensor_msgs::image_encodings::MONO16;
  image.step = m.cols * 2;
  image.data.resize(image.step * m.rows);
  for (int r = 0; r < m.rows; ++r) std::memcpy(&image.data[r * image.step], m.ptr(r), image.step);
  return image;
}

sensor_msgs::Image image8(const std::string& encoding, int width, int height, int channels,
                          const std::vector<uint8_t>& pixel) {
  sensor_msgs::Image image;
  image.width = width;
  image.height = height;
  image.encoding = encoding;
  image.step = width * channels;
  image.data.resize(image.step * height);
  for (size_t i = 0; i < image.data.size(); ++i) image.data[i] = pixel[i % pixel.size()];
  return image;
}

// A Bayer mosaic of one colour: pattern names the top-left 2 x 2 cell ("rggb": R G / G B).
sensor_msgs::Image bayerOf(const std::string& pattern, uint8_t r, uint8_t g, uint8_t b, int side) {
  sensor_msgs::Image image = image8("bayer_" + pattern + "8", side, side, 1, {0});
  for (int y = 0; y < side; ++y) {
    for (int x = 0; x < side; ++x) {
      const char channel = pattern[2 * (y % 2) + x % 2];
      image.data[y * image.step + x] = channel == 'r' ? r : channel == 'g' ? g : b;
    }
  }
  return image;
}

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The backquoted names in `text` that look like encodings.
std::set<std::string> quotedNames(const std::string& text) {
  std::set<std::string> names;
  const std::regex quoted("`([A-Za-z0-9_]+)`");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), quoted); it != std::sregex_iterator(); ++it)
    names.insert((*it)[1]);
  return names;
}

}  // namespace

TEST(RosConversions, BayerMosaicsOfEveryPatternGiveTheColoursGrey) {
  // R 200, G 100, B 50: grey 0.299 R + 0.587 G + 0.114 B = 124.2. A mosaic read with another
  // pattern mixes R and B the other way (96.5) or takes R or B for G.
  for (const std::string pattern : {"rggb", "bggr", "gbrg", "grbg"}) {
    const cv::Mat gray = conv::toGray(bayerOf(pattern, 200, 100, 50, 8), 0);
    ASSERT_EQ(gray.type(), CV_8UC1);
    ASSERT_EQ(gray.size(), cv::Size(8, 8));
    for (int y = 2; y < 6; ++y)
      for (int x = 2; x < 6; ++x) EXPECT_NEAR(gray.at<uint8_t>(y, x), 124, 2) << pattern << " at " << x << "," << y;
  }
  EXPECT_NO_THROW(conv::toGray(bayerOf("rggb", 200, 100, 50, 2), 0));
  EXPECT_THROW(conv::toGray(image8("bayer_rggb8", 1, 4, 1, {9}), 0), std::invalid_argument);
  EXPECT_THROW(conv::toGray(image8("bayer_rggb16", 4, 4, 2, {9}), 0), std::invalid_argument);
}

TEST(RosConversions, Yuv422GivesItsLumaSamples) {
  // UYVY (ROS's yuv422): U Y0 V Y1; YUYV (yuv422_yuy2): Y0 U Y1 V.
  const cv::Mat uyvy = conv::toGray(image8("yuv422", 4, 2, 2, {128, 30, 128, 220}), 0);
  const cv::Mat yuyv = conv::toGray(image8("yuv422_yuy2", 4, 2, 2, {30, 128, 220, 128}), 0);
  for (const cv::Mat& gray : {uyvy, yuyv}) {
    ASSERT_EQ(gray.type(), CV_8UC1);
    ASSERT_EQ(gray.size(), cv::Size(4, 2));
    for (int y = 0; y < 2; ++y) {
      for (int x = 0; x < 4; ++x) EXPECT_EQ(gray.at<uint8_t>(y, x), x % 2 == 0 ? 30 : 220);
    }
  }
  // Pixel pairs share their chroma: an odd width is malformed.
  EXPECT_THROW(conv::toGray(image8("yuv422", 3, 2, 2, {128, 30}), 0), std::invalid_argument);
  // 8UC1 is taken as mono8, shared with the message.
  const sensor_msgs::Image plain = image8("8UC1", 4, 4, 1, {77});
  const cv::Mat shared = conv::toGray(plain, 0);
  EXPECT_EQ(shared.data, plain.data.data());
}

// README.md and doc/ros.md list the accepted encodings; they must be the conversion's.
TEST(RosConversions, DocsListTheSupportedEncodings) {
  const std::vector<std::string> supported = conv::supportedEncodings();
  const std::set<std::string> expected(supported.begin(), supported.end());
  const std::string repo = VISUAL_GYRO_SOURCE_DIR;
  const std::string readme = readFile(repo + "/README.md");
  const std::regex readme_row("\\| `<camera>/<image>`[^|]*\\|[^|]*\\| ([^;|]*);");
  std::smatch row;
  ASSERT_TRUE(std::regex_search(readme, row, readme_row)) << "README.md has no image row";
  EXPECT_EQ(quotedNames(row[1]), expected) << "README.md's image row: " << row[1];
  const std::string ros = readFile(repo + "/doc/ros.md");
  const std::regex ros_sentence("Accepted encodings: ([^.]*), all converted to gr");
  std::smatch sentence;
  ASSERT_TRUE(std::regex_search(ros, sentence, ros_sentence)) << "doc/ros.md names no accepted encodings";
  EXPECT_EQ(quotedNames(sentence[1]), expected) << "doc/ros.md: " << sentence[1];
  const std::string front_end = readFile(repo + "/doc/front_end.md");
  for (const std::string& name : supported) EXPECT_NE(front_end.find("`" + name + "`"), std::string::npos) << name;
  const std::vector<std::string> unsupported = {"32FC1", "bayer_rggb16", "rgb16"};
  for (const std::string& name : unsupported) EXPECT_FALSE(conv::isSupportedEncoding(name)) << name;
}

TEST(RosConversions, Mono16ScaleHasNoStateAcrossFrames) {
  cv::Mat twelve_bit(4, 4, CV_16UC1, cv::Scalar(2048));  // mid-grey of a 12-bit camera
  twelve_bit.at<uint16_t>(0, 0) = 4095;
  cv::Mat bright = twelve_bit.clone();
  bright.at<uint16_t>(1, 1) = 65535;  // one pixel beyond 12 bits
  const cv::Mat a = conv::toGray(mono16(twelve_bit), 0);
  EXPECT_NEAR(a.at<uint8_t>(2, 2), 128, 1);
  const cv::Mat b = conv::toGray(mono16(bright), 0);
  EXPECT_LE(b.at<uint8_t>(2, 2), 9);  // this frame alone is scaled by its 16-bit maximum
  const cv::Mat c = conv::toGray(mono16(twelve_bit), 0);
  EXPECT_NEAR(c.at<uint8_t>(2, 2), 128, 1) << "the bright frame changed the next frame's scale";
  // A declared bit depth: constant scale, the outlier saturates.
  const cv::Mat d = conv::toGray(mono16(bright), 12);
  EXPECT_NEAR(d.at<uint8_t>(2, 2), 128, 1);
  EXPECT_EQ(d.at<uint8_t>(1, 1), 255);
  EXPECT_THROW(conv::toGray(mono16(twelve_bit), 7), std::invalid_argument);
  EXPECT_THROW(conv::toGray(mono16(twelve_bit), 17), std::invalid_argument);
}

TEST(RosConversions, MalformedImagesThrowInvalidArgument) {
  sensor_msgs::Image odd = mono16(cv::Mat(2, 2, CV_16UC1, cv::Scalar(7)));
  odd.step = 5;  // not a multiple of 2 bytes (found by make fuzz: OpenCV threw its own exception)
  odd.data.resize(odd.step * odd.height);
  EXPECT_THROW(conv::toGray(odd, 0), std::invalid_argument);
  sensor_msgs::Image huge = odd;
  huge.encoding = sensor_msgs::image_encodings::MONO8;
  huge.width = 1u << 30;
  huge.step = 1u << 30;
  EXPECT_THROW(conv::toGray(huge, 0), std::invalid_argument);
}

TEST(RosConversions, BinningThatLeavesNoImageIsNamed) {
  sensor_msgs::CameraInfo info;
  info.width = 1241;
  info.height = 376;
  info.K = {700, 0, 620, 0, 700, 188, 0, 0, 1};
  info.binning_x = 1000000;
  visual_gyro::CameraModel model;
  std::string why;
  EXPECT_FALSE(conv::cameraModelFromInfo(info, &model, &why));
  EXPECT_NE(why.find("binning"), std::string::npos) << why;
}

TEST(RosConversions, RationalPolynomialCameraInfo) {
  sensor_msgs::CameraInfo info;
  info.width = 1280;
  info.height = 720;
  info.K = {607.0, 0, 638.6, 0, 606.9, 366.5, 0, 0, 1};
  info.distortion_model = sensor_msgs::distortion_models::RATIONAL_POLYNOMIAL;
  info.D = {0.5959, -2.8526, 0.000642, -0.000302, 1.6468, 0.4719, -2.6814, 1.5750};
  visual_gyro::CameraModel model;
  std::string why;
  ASSERT_TRUE(conv::cameraModelFromInfo(info, &model, &why)) << why;
  const visual_gyro::CameraModel direct(607.0, 606.9, 638.6, 366.5, 1280, 720,
                                        visual_gyro::DistortionModel::kPlumbBob, info.D);
  EXPECT_EQ(model.distortion(), info.D);
  EXPECT_EQ(model.bearing(10.0, 700.0), direct.bearing(10.0, 700.0));
  // Back to a CameraInfo under the same name and coefficients.
  const sensor_msgs::CameraInfo again = conv::cameraInfoFromModel(model);
  EXPECT_EQ(again.distortion_model, sensor_msgs::distortion_models::RATIONAL_POLYNOMIAL);
  EXPECT_EQ(again.D, info.D);

  // Drivers that publish OpenCV's fourteen coefficients: the thin-prism and tilt terms must be
  // zero, or the message is refused with the reason.
  info.D.resize(14, 0.0);
  ASSERT_TRUE(conv::cameraModelFromInfo(info, &model, &why)) << why;
  EXPECT_EQ(model.bearing(10.0, 700.0), direct.bearing(10.0, 700.0));
  info.D[8] = 0.01;
  EXPECT_FALSE(conv::cameraModelFromInfo(info, &model, &why));
  EXPECT_NE(why.find("D[8]"), std::string::npos) << why;
}
