// ROS conversions without a master: mono16 scaling without state, malformed images found by the
// fuzzer, CameraInfo binning that leaves no image, the rational_polynomial distortion model.
#include <gtest/gtest.h>

#include <cstring>

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

}  // namespace

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
