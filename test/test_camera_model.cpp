// Camera model: pixel <-> bearing round trips with and without distortion, validation, parsing.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/calib3d.hpp>

#include "visual_gyro/camera_model.h"

namespace visual_gyro {
namespace {

CameraModel eurocRadTan() {
  return CameraModel(458.654, 457.296, 367.215, 248.375, 752, 480, DistortionModel::kPlumbBob,
                     {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05});
}

// A wide-angle lens with equidistant coefficients of a real (TUM-VI, Kalibr) calibration; the
// focal length keeps the image corners within 90 degrees of the axis.
CameraModel equidistantFisheye() {
  return CameraModel(350.0, 349.5, 321.3, 238.7, 640, 480, DistortionModel::kEquidistant,
                     {0.0034823894022493434, 0.0007150348452162257, -0.0020532361418706202,
                      0.00020293673591811182});
}

/// Largest pixel error of pixel -> bearing -> pixel over a grid covering the whole image,
/// corners included; also checks that every bearing has unit length.
double maxRoundTripError(const CameraModel& camera, double step) {
  double worst = 0.0;
  for (double v = 0.0; v <= camera.height() - 1 + 1e-9; v += step) {
    for (double u = 0.0; u <= camera.width() - 1 + 1e-9; u += step) {
      const Eigen::Vector3d b = camera.bearing(u, v);
      EXPECT_NEAR(b.norm(), 1.0, 1e-12) << "at (" << u << ", " << v << ")";
      EXPECT_GT(b.z(), 0.0) << "at (" << u << ", " << v << ")";
      const Eigen::Vector2d p = camera.project(b);
      const double error = std::hypot(p.x() - u, p.y() - v);
      if (!(error <= worst)) worst = error;  // NaN propagates as a failure
    }
  }
  std::printf("max round-trip error %.3g px\n", worst);
  return worst;
}

TEST(CameraModel, EurocRadTanRoundTrip) {
  const CameraModel camera = eurocRadTan();
  ASSERT_EQ(camera.validate(), "");
  const double error = maxRoundTripError(camera, 7.5);
  EXPECT_LT(error, 1e-6) << "max round-trip error " << error << " px";
  // The image corner of this strongly distorted lens must map to a ray clearly outside the
  // pinhole ray of the same pixel (distortion really is removed, not ignored).
  const Eigen::Vector3d corner = camera.bearing(0.0, 0.0);
  const Eigen::Vector3d pinhole =
      Eigen::Vector3d(-367.215 / 458.654, -248.375 / 457.296, 1.0).normalized();
  EXPECT_GT(std::acos(std::min(1.0, corner.dot(pinhole))), 0.05);
}

TEST(CameraModel, RadTanWithK3RoundTrip) {
  const CameraModel camera(700.0, 705.0, 640.0, 360.0, 1280, 720, DistortionModel::kPlumbBob,
                           {-0.3, 0.12, 0.001, -0.0005, -0.02});
  ASSERT_EQ(camera.validate(), "");
  const double error = maxRoundTripError(camera, 10.0);
  EXPECT_LT(error, 1e-6) << "max round-trip error " << error << " px";
}

TEST(CameraModel, EquidistantRoundTrip) {
  const CameraModel camera = equidistantFisheye();
  ASSERT_EQ(camera.validate(), "");
  const double error = maxRoundTripError(camera, 5.0);
  EXPECT_LT(error, 1e-6) << "max round-trip error " << error << " px";
  // The corner ray is about 1.14 rad off axis (400 px at f = 350 px); a pinhole would say 0.85.
  const Eigen::Vector3d corner = camera.bearing(0.0, 0.0);
  EXPECT_GT(std::acos(corner.z()), 1.05);
}

TEST(CameraModel, NoneRoundTripAndPinholeBearing) {
  const CameraModel camera(707.0912, 707.0912, 601.8873, 183.1104, 1241, 376);
  ASSERT_EQ(camera.validate(), "");
  const double error = maxRoundTripError(camera, 10.0);
  EXPECT_LT(error, 1e-6) << "max round-trip error " << error << " px";
  const Eigen::Vector3d b = camera.bearing(1000.0, 50.0);
  const Eigen::Vector3d expected =
      Eigen::Vector3d((1000.0 - 601.8873) / 707.0912, (50.0 - 183.1104) / 707.0912, 1.0)
          .normalized();
  EXPECT_LT((b - expected).norm(), 1e-14);
}

/// project() of bearings over the image against OpenCV's own implementation of the model, so a
/// self-consistent but wrong formula cannot pass the round-trip tests.
void expectMatchesOpenCv(const CameraModel& camera) {
  std::vector<cv::Point3d> rays;
  std::vector<Eigen::Vector3d> bearings;
  for (double v = 0.0; v < camera.height(); v += 40.0) {
    for (double u = 0.0; u < camera.width(); u += 40.0) {
      bearings.push_back(camera.bearing(u, v));
      rays.emplace_back(bearings.back().x(), bearings.back().y(), bearings.back().z());
    }
  }
  const cv::Matx33d K(camera.fx(), 0, camera.cx(), 0, camera.fy(), camera.cy(), 0, 0, 1);
  const cv::Vec3d zero(0, 0, 0);
  std::vector<cv::Point2d> expected;
  if (camera.distortionModel() == DistortionModel::kEquidistant) {
    cv::fisheye::projectPoints(rays, expected, zero, zero, K, camera.distortion());
  } else {
    cv::projectPoints(rays, zero, zero, K, camera.distortion(), expected);
  }
  for (size_t i = 0; i < rays.size(); ++i) {
    const Eigen::Vector2d p = camera.project(bearings[i]);
    EXPECT_NEAR(p.x(), expected[i].x, 1e-6);
    EXPECT_NEAR(p.y(), expected[i].y, 1e-6);
  }
}

TEST(CameraModel, DistortionAgreesWithOpenCv) {
  expectMatchesOpenCv(eurocRadTan());
  expectMatchesOpenCv(CameraModel(700.0, 705.0, 640.0, 360.0, 1280, 720, DistortionModel::kPlumbBob,
                                  {-0.3, 0.12, 0.001, -0.0005, -0.02}));
  expectMatchesOpenCv(equidistantFisheye());
}

TEST(CameraModel, ZeroPlumbBobBehavesAsNone) {
  const CameraModel zero(500.0, 500.0, 320.0, 240.0, 640, 480, DistortionModel::kPlumbBob,
                         {0.0, 0.0, 0.0, 0.0, 0.0});
  const CameraModel none(500.0, 500.0, 320.0, 240.0, 640, 480);
  ASSERT_EQ(zero.validate(), "");
  for (double u : {0.0, 100.5, 639.0}) {
    for (double v : {0.0, 240.0, 479.0}) {
      EXPECT_EQ(zero.bearing(u, v), none.bearing(u, v));
      EXPECT_EQ(zero.project(none.bearing(u, v)), none.project(none.bearing(u, v)));
    }
  }
}

TEST(CameraModel, PrincipalPointBearingIsOpticalAxis) {
  for (const CameraModel& camera :
       {eurocRadTan(), equidistantFisheye(), CameraModel(707.0, 707.0, 601.9, 183.1, 1241, 376)}) {
    const Eigen::Vector3d b = camera.bearing(camera.cx(), camera.cy());
    EXPECT_NEAR(b.x(), 0.0, 1e-12);
    EXPECT_NEAR(b.y(), 0.0, 1e-12);
    EXPECT_NEAR(b.z(), 1.0, 1e-12);
    const Eigen::Vector2d p = camera.project(Eigen::Vector3d(0.0, 0.0, 1.0));
    EXPECT_NEAR(p.x(), camera.cx(), 1e-12);
    EXPECT_NEAR(p.y(), camera.cy(), 1e-12);
  }
}

TEST(CameraModel, OpticalFrameAxes) {
  // x right, y down: a pixel right of and below the principal point has x > 0 and y > 0.
  const CameraModel camera = eurocRadTan();
  const Eigen::Vector3d b = camera.bearing(500.0, 400.0);
  EXPECT_GT(b.x(), 0.0);
  EXPECT_GT(b.y(), 0.0);
  EXPECT_GT(b.z(), 0.0);
}

TEST(CameraModel, ProjectBehindCameraIsInvalid) {
  const CameraModel camera = eurocRadTan();
  const Eigen::Vector2d p = camera.project(Eigen::Vector3d(0.1, 0.0, -1.0));
  EXPECT_FALSE(std::isfinite(p.x()) && std::isfinite(p.y()));
}

TEST(CameraModel, ValidateNamesTheProblem) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(CameraModel().validate().find("focal"), 0u) << CameraModel().validate();

  std::string why = CameraModel(nan, 500.0, 320.0, 240.0, 640, 480).validate();
  EXPECT_NE(why.find("focal"), std::string::npos) << why;
  EXPECT_NE(why.find("finite"), std::string::npos) << why;

  why = CameraModel(500.0, inf, 320.0, 240.0, 640, 480).validate();
  EXPECT_NE(why.find("focal"), std::string::npos) << why;

  why = CameraModel(-500.0, 500.0, 320.0, 240.0, 640, 480).validate();
  EXPECT_NE(why.find("focal"), std::string::npos) << why;
  EXPECT_NE(why.find("positive"), std::string::npos) << why;

  why = CameraModel(500.0, 500.0, nan, 240.0, 640, 480).validate();
  EXPECT_NE(why.find("principal point"), std::string::npos) << why;

  why = CameraModel(500.0, 500.0, 320.0, 240.0, 0, 480).validate();
  EXPECT_NE(why.find("image size"), std::string::npos) << why;

  why = CameraModel(500.0, 500.0, 320.0, 240.0, 640, 480, DistortionModel::kPlumbBob,
                    {-0.28, 0.07, 0.0})
            .validate();
  EXPECT_NE(why.find("coefficients"), std::string::npos) << why;
  EXPECT_NE(why.find("got 3"), std::string::npos) << why;

  why = CameraModel(500.0, 500.0, 320.0, 240.0, 640, 480, DistortionModel::kEquidistant,
                    {0.01, 0.0, 0.0, 0.0, 0.0})
            .validate();
  EXPECT_NE(why.find("equidistant"), std::string::npos) << why;
  EXPECT_NE(why.find("got 5"), std::string::npos) << why;

  why = CameraModel(500.0, 500.0, 320.0, 240.0, 640, 480, DistortionModel::kPlumbBob,
                    {-0.28, nan, 0.0, 0.0})
            .validate();
  EXPECT_NE(why.find("distortion"), std::string::npos) << why;
  EXPECT_NE(why.find("finite"), std::string::npos) << why;

  why = CameraModel(500.0, 500.0, 320.0, 240.0, 640, 480, DistortionModel::kNone, {0.1, 0.0})
            .validate();
  EXPECT_NE(why.find("none"), std::string::npos) << why;

  // Usable models.
  EXPECT_EQ(CameraModel(500.0, 500.0, 320.0, 240.0, 640, 480, DistortionModel::kNone,
                        {0.0, 0.0, 0.0, 0.0, 0.0})
                .validate(),
            "");
  EXPECT_EQ(eurocRadTan().validate(), "");
}

TEST(CameraModel, InvalidDistortionGivesNonFiniteNotGarbage) {
  const CameraModel camera(500.0, 500.0, 320.0, 240.0, 640, 480, DistortionModel::kPlumbBob,
                           {-0.28, 0.07, 0.001});
  ASSERT_NE(camera.validate(), "");
  EXPECT_FALSE(camera.bearing(100.0, 100.0).allFinite());
  EXPECT_FALSE(camera.project(Eigen::Vector3d(0.1, 0.1, 1.0).normalized()).allFinite());
}

TEST(ParseDistortionModel, KnownAndUnknownNames) {
  DistortionModel model = DistortionModel::kEquidistant;
  EXPECT_TRUE(parseDistortionModel("plumb_bob", &model));
  EXPECT_EQ(model, DistortionModel::kPlumbBob);
  model = DistortionModel::kNone;
  EXPECT_TRUE(parseDistortionModel("radtan", &model));
  EXPECT_EQ(model, DistortionModel::kPlumbBob);
  model = DistortionModel::kNone;
  EXPECT_TRUE(parseDistortionModel("radial-tangential", &model));
  EXPECT_EQ(model, DistortionModel::kPlumbBob);
  EXPECT_TRUE(parseDistortionModel("equidistant", &model));
  EXPECT_EQ(model, DistortionModel::kEquidistant);
  EXPECT_TRUE(parseDistortionModel("", &model));
  EXPECT_EQ(model, DistortionModel::kNone);
  model = DistortionModel::kPlumbBob;
  EXPECT_TRUE(parseDistortionModel("none", &model));
  EXPECT_EQ(model, DistortionModel::kNone);

  model = DistortionModel::kEquidistant;
  EXPECT_FALSE(parseDistortionModel("rational_polynomial", &model));
  EXPECT_FALSE(parseDistortionModel("pinhole-radtan-garbage", &model));
  EXPECT_EQ(model, DistortionModel::kEquidistant) << "an unknown name must leave *model alone";
}

}  // namespace
}  // namespace visual_gyro
