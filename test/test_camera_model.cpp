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

// OpenCV's rational model (k1 k2 p1 p2 k3 k4 k5 k6), with coefficients of the size depth cameras
// publish as "rational_polynomial": large terms that nearly cancel between numerator and
// denominator (the radial factor stays within a few percent of 1 over the image).
CameraModel rationalPolynomial() {
  return CameraModel(607.0, 606.9, 638.6, 366.5, 1280, 720, DistortionModel::kPlumbBob,
                     {0.5959, -2.8526, 0.000642, -0.000302, 1.6468, 0.4719, -2.6814, 1.5750});
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

TEST(CameraModel, RationalPolynomialRoundTrip) {
  const CameraModel camera = rationalPolynomial();
  ASSERT_EQ(camera.validate(), "");
  EXPECT_EQ(calibrationProblem(camera), "");
  const double error = maxRoundTripError(camera, 10.0);
  EXPECT_LT(error, 1e-6) << "max round-trip error " << error << " px";
  // With k4..k6 zero the rational model is the five-coefficient one, to the bit.
  const CameraModel five(700.0, 705.0, 640.0, 360.0, 1280, 720, DistortionModel::kPlumbBob,
                         {-0.3, 0.12, 0.001, -0.0005, -0.02});
  const CameraModel eight(700.0, 705.0, 640.0, 360.0, 1280, 720, DistortionModel::kPlumbBob,
                          {-0.3, 0.12, 0.001, -0.0005, -0.02, 0.0, 0.0, 0.0});
  for (const Eigen::Vector2d& pixel : {Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(333.3, 500.0)}) {
    EXPECT_EQ(five.bearing(pixel.x(), pixel.y()), eight.bearing(pixel.x(), pixel.y()));
    EXPECT_EQ(five.project(five.bearing(pixel.x(), pixel.y())), eight.project(five.bearing(pixel.x(), pixel.y())));
  }
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
  expectMatchesOpenCv(rationalPolynomial());
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

  why = CameraModel(500.0, 500.0, 320.0, 240.0, 640, 480, DistortionModel::kPlumbBob,
                    {-0.28, 0.07, 0.0, 0.0, 0.0, 0.1, 0.0})
            .validate();
  EXPECT_NE(why.find("4, 5 or 8 coefficients"), std::string::npos) << why;
  EXPECT_NE(why.find("got 7"), std::string::npos) << why;

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

// ---------------------------------------------------------------------------------------------
// calibrationProblem(): calibrations that do not fit their images
// ---------------------------------------------------------------------------------------------

bool contains(const std::string& text, const std::string& needle) {
  return text.find(needle) != std::string::npos;
}

/// kitti_turn's camera (calib.txt), with `model` and `d` instead of its (absent) distortion.
CameraModel kittiTurn(DistortionModel model = DistortionModel::kNone, const std::vector<double>& d = {}) {
  return CameraModel(718.856, 718.856, 607.1928, 185.2157, 1241, 376, model, d);
}

TEST(CalibrationProblem, CamerasOfTheSharedAndRenderedSequencesPass) {
  EXPECT_EQ(calibrationProblem(kittiTurn()), "");
  EXPECT_EQ(calibrationProblem(CameraModel(707.0912, 707.0912, 601.8873, 183.1104, 1226, 370)), "");
  EXPECT_EQ(calibrationProblem(eurocRadTan()), "");
  // The renderer's default camera and its centred cameras of other sizes.
  EXPECT_EQ(calibrationProblem(CameraModel(500.0, 500.0, 319.5, 239.5, 640, 480)), "");
  EXPECT_EQ(calibrationProblem(CameraModel(250.0, 250.0, 159.5, 119.5, 320, 240)), "");
  EXPECT_EQ(calibrationProblem(CameraModel(40.0, 40.0, 31.5, 23.5, 64, 48)), "");
  // Real lenses: a wide fisheye, TUM-VI's (whose image corners lie 115 deg off axis, outside the
  // lens's image circle), a strong radial-tangential lens with k3, and a pinhole lens written as
  // equidistant (the tangent's series: k1 = 1/3, k2 = 2/15, k3 = 17/315).
  EXPECT_EQ(calibrationProblem(equidistantFisheye()), "");
  EXPECT_EQ(calibrationProblem(CameraModel(190.97, 190.97, 254.93, 256.89, 512, 512, DistortionModel::kEquidistant,
                                           {0.0034823, 0.0007150, -0.0020532, 0.0002029})),
            "");
  EXPECT_EQ(calibrationProblem(CameraModel(700.0, 705.0, 640.0, 360.0, 1280, 720, DistortionModel::kPlumbBob,
                                           {-0.3, 0.12, 0.001, -0.0005, -0.02})),
            "");
  EXPECT_EQ(calibrationProblem(kittiTurn(DistortionModel::kEquidistant, {1.0 / 3, 2.0 / 15, 17.0 / 315, 0.0})), "");
}

// Calibrations that gave valid, confident and wrong rates on kitti_turn (true rate about
// +0.45 rad/s about y): each is refused, naming what is wrong and the numbers.
TEST(CalibrationProblem, KittiFramesWithAWrongCalibrationAreRefused) {
  std::string why = calibrationProblem(kittiTurn(DistortionModel::kPlumbBob, {5.0, 0.0, 0.0, 0.0, 0.0}));
  EXPECT_TRUE(contains(why, "plumb_bob distortion shrinks the field of view")) << why;
  EXPECT_TRUE(contains(why, "0.578 times the undistorted pinhole's 41.5 deg")) << why;

  why = calibrationProblem(kittiTurn(DistortionModel::kEquidistant, {3.0, 0.0, 0.0, 0.0}));
  EXPECT_TRUE(contains(why, "equidistant distortion shrinks the field of view")) << why;

  why = calibrationProblem(kittiTurn(DistortionModel::kPlumbBob, {50.0, -300.0, 1.0, 1.0, 900.0}));
  EXPECT_TRUE(contains(why, "plumb_bob distortion shrinks the field of view")) << why;

  why = calibrationProblem(CameraModel(718.856, 718.856, 1240.0, 375.0, 1241, 376));
  EXPECT_TRUE(contains(why, "principal point (1240, 375) lies at 100.0 % / 99.9 % of the 1241x376 image, "
                            "outside its central 60 %"))
      << why;
}

TEST(CalibrationProblem, PrincipalPointWithinTheCentralSixtyPercent) {
  // 20 % from either side in each axis is the bound (pixel edges: (c + 0.5) / size).
  auto camera = [](double cx, double cy) { return CameraModel(500.0, 500.0, cx, cy, 640, 480); };
  EXPECT_EQ(calibrationProblem(camera(0.21 * 640 - 0.5, 239.5)), "");
  EXPECT_EQ(calibrationProblem(camera(0.79 * 640 - 0.5, 0.79 * 480 - 0.5)), "");
  EXPECT_TRUE(contains(calibrationProblem(camera(0.19 * 640 - 0.5, 239.5)), "outside its central 60 %"));
  EXPECT_TRUE(contains(calibrationProblem(camera(319.5, 0.81 * 480 - 0.5)), "outside its central 60 %"));
  EXPECT_TRUE(contains(calibrationProblem(camera(319.5, -3.0)), "lies outside the 640x480 image"));
}

TEST(CalibrationProblem, FieldOfViewBoundsPerModel) {
  // Pincushion just inside and beyond 0.8 of the pinhole's angle at KITTI's corners (0.85 and 0.78).
  EXPECT_EQ(calibrationProblem(kittiTurn(DistortionModel::kPlumbBob, {0.5, 0.0, 0.0, 0.0})), "");
  EXPECT_TRUE(contains(calibrationProblem(kittiTurn(DistortionModel::kPlumbBob, {1.0, 0.0, 0.0, 0.0})),
                       "shrinks the field of view"));
  // A plumb_bob lens wider than 150 deg diagonally (a 640x480 image at f = 100 px: 152 deg as a
  // pinhole already; mild barrel distortion keeps it monotonic).
  const std::string wide = calibrationProblem(
      CameraModel(100.0, 100.0, 319.5, 239.5, 640, 480, DistortionModel::kPlumbBob, {-0.001, 0.0, 0.0, 0.0}));
  EXPECT_TRUE(contains(wide, "diagonal field of view of")) << wide;
  EXPECT_TRUE(contains(wide, "use equidistant for wider lenses")) << wide;
  // A 190 deg fisheye is fine (left and right edges 95 deg off axis, corners 119 deg); one whose
  // coefficients put the edges beyond 1.6 times the ideal fisheye's angle is not, nor one whose
  // edges lie beyond 100 deg.
  EXPECT_EQ(calibrationProblem(CameraModel(193.0, 193.0, 319.5, 239.5, 640, 480, DistortionModel::kEquidistant,
                                           {0.001, 0.0, 0.0, 0.0})),
            "");
  const std::string beyond = calibrationProblem(
      CameraModel(160.0, 160.0, 319.5, 239.5, 640, 480, DistortionModel::kEquidistant, {0.001, 0.0, 0.0, 0.0}));
  EXPECT_TRUE(contains(beyond, "the right edge lies 114 deg from the optical axis")) << beyond;
  const std::string widened = calibrationProblem(
      CameraModel(500.0, 500.0, 320.0, 240.0, 640, 480, DistortionModel::kEquidistant,
                  {3.52125, -3.66551, -0.754312, 0.687941}));
  EXPECT_TRUE(contains(widened, "equidistant distortion widens the field of view implausibly")) << widened;
}

TEST(CalibrationProblem, DistortionThatCannotBeInvertedOverTheImage) {
  // No direction maps onto the image's corner: undistortion stalls and the corner's bearing
  // would come from nowhere.
  std::string why = calibrationProblem(
      CameraModel(500.0, 500.0, 320.0, 240.0, 640, 480, DistortionModel::kPlumbBob,
                  {-0.198011, 0.25939, 0.0459686, 0.034291, -0.144123}));
  EXPECT_TRUE(contains(why, "plumb_bob distortion cannot be inverted at the top-left corner")) << why;
  why = calibrationProblem(
      CameraModel(500.0, 500.0, 320.0, 240.0, 640, 480, DistortionModel::kEquidistant,
                  {0.0345591, -0.228005, -0.0280194, 0.0211694}));
  EXPECT_TRUE(contains(why, "equidistant distortion cannot be inverted")) << why;
}

TEST(CalibrationProblem, RationalDenominatorThatVanishesInsideTheImage) {
  // 1 - r^2 in the denominator: the radial factor has a pole at r = 1, inside the image (its
  // corners lie at r = 1.2); beyond it the model maps rays back across the principal point.
  const std::string why = calibrationProblem(CameraModel(607.0, 606.9, 638.6, 366.5, 1280, 720,
                                                         DistortionModel::kPlumbBob,
                                                         {0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0}));
  EXPECT_TRUE(contains(why, "rational_polynomial distortion cannot be inverted")) << why;
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

  model = DistortionModel::kNone;
  EXPECT_TRUE(parseDistortionModel("rational_polynomial", &model));
  EXPECT_EQ(model, DistortionModel::kPlumbBob);

  model = DistortionModel::kEquidistant;
  EXPECT_FALSE(parseDistortionModel("pinhole-radtan-garbage", &model));
  EXPECT_EQ(model, DistortionModel::kEquidistant) << "an unknown name must leave *model alone";
}

}  // namespace
}  // namespace visual_gyro
