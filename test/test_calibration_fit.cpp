// The calibration check at run time: residuals of neighbouring matches correlate when the camera
// model does not fit the images, not when they are pixel noise; the pipeline invalidates its
// estimates while they do.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "test_support.h"
#include "visual_gyro/calibration_fit.h"
#include "visual_gyro/geometry.h"
#include "visual_gyro/renderer.h"
#include "visual_gyro/visual_gyro.h"

namespace vg = visual_gyro;

namespace {

constexpr double kFocal = 500.0;  // [px], 640 x 480 image
constexpr double kGate = 0.1 * vg::kDegToRad;

/// Matches of a rotation by `rotation` (b_prev = R b_cur) over a 640 x 480 pinhole image: the
/// previous bearings moved by `field(u, v)` [px] plus independent noise of `noise_px` per axis.
struct Matches {
  std::vector<Eigen::Vector3d> previous, current;
};

template <class Field>
Matches makeMatches(const Eigen::Matrix3d& rotation, double noise_px, Field field, int count = 800) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 639.0), v(0.0, 479.0);
  std::normal_distribution<double> noise(0.0, noise_px);
  Matches m;
  for (int i = 0; i < count; ++i) {
    const double x = u(rng), y = v(rng);
    const Eigen::Vector3d current = Eigen::Vector3d((x - 319.5) / kFocal, (y - 239.5) / kFocal, 1.0).normalized();
    const Eigen::Vector3d exact = rotation * current;
    const Eigen::Vector2d shift = field(x, y) + Eigen::Vector2d(noise(rng), noise(rng));
    const Eigen::Vector3d moved(exact.x() / exact.z() + shift.x() / kFocal, exact.y() / exact.z() + shift.y() / kFocal,
                                1.0);
    m.previous.push_back(moved.normalized());
    m.current.push_back(current);
  }
  return m;
}

const Eigen::Matrix3d kYaw = Eigen::AngleAxisd(2.0 * vg::kDegToRad, Eigen::Vector3d::UnitY()).toRotationMatrix();

}  // namespace

TEST(ResidualCorrelation, PixelNoiseIsUncorrelatedHoweverLarge) {
  vg::ResidualCorrelation correlation;
  for (const double noise : {0.1, 0.3, 1.0}) {
    const Matches m = makeMatches(kYaw, noise, [](double, double) { return Eigen::Vector2d::Zero(); });
    const double c = correlation.compute(m.previous, m.current, kYaw, Eigen::Vector3d::Zero(), 1.0 / kFocal, kGate);
    EXPECT_LT(std::abs(c), 0.12) << "noise " << noise << " px";
  }
}

TEST(ResidualCorrelation, ASmoothErrorFieldCorrelates) {
  // A radial error growing to 2 px at the corners (a wrong k1), with 0.3 px of pixel noise.
  auto radial = [](double x, double y) {
    const Eigen::Vector2d r((x - 319.5) / 400.0, (y - 239.5) / 400.0);
    return Eigen::Vector2d(2.0 * r * r.squaredNorm());
  };
  const Matches m = makeMatches(kYaw, 0.3, radial);
  vg::ResidualCorrelation correlation;
  const double c = correlation.compute(m.previous, m.current, kYaw, Eigen::Vector3d::Zero(), 1.0 / kFocal, kGate);
  EXPECT_GT(c, 0.5);
}

TEST(ResidualCorrelation, ParallaxAlongTheEpipolarLinesIsNotAnError) {
  // Translation along x: the parallax of each point lies along its epipolar line (horizontal
  // here) and is shared by neighbours at similar depth; it must not count.
  const Eigen::Vector3d t = Eigen::Vector3d::UnitX();
  auto parallax = [](double x, double y) { return Eigen::Vector2d(3.0 + 2.0 * std::sin(x / 90.0 + y / 70.0), 0.0); };
  const Matches m = makeMatches(Eigen::Matrix3d::Identity(), 0.3, parallax);
  vg::ResidualCorrelation correlation;
  const double with_translation =
      correlation.compute(m.previous, m.current, Eigen::Matrix3d::Identity(), t, 1.0 / kFocal, kGate);
  EXPECT_LT(std::abs(with_translation), 0.12);
  // The same matches read as a pure rotation would blame the (smooth) parallax.
  const double without = correlation.compute(m.previous, m.current, Eigen::Matrix3d::Identity(),
                                             Eigen::Vector3d::Zero(), 1.0 / kFocal, kGate);
  EXPECT_GT(without, 0.5);
}

TEST(ResidualCorrelation, ARollingShuttersSkewIsNoErrorOnceModelled) {
  // A rotation that changes down the image (a rolling shutter under a changing rate): each match's
  // rotation is R exp(s e), s its row (matchRow), with 0.3 px of pixel noise.
  const Eigen::Vector3d skew = Eigen::Vector3d(0.3, -0.4, 0.1) * vg::kDegToRad;
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(0.0, 639.0), v(0.0, 479.0);
  std::normal_distribution<double> noise(0.0, 0.3 / kFocal);
  Matches m;
  for (int i = 0; i < 800; ++i) {
    const Eigen::Vector3d current = Eigen::Vector3d((u(rng) - 319.5) / kFocal, (v(rng) - 239.5) / kFocal, 1.0).normalized();
    Eigen::Vector3d previous = kYaw * current;
    for (int k = 0; k < 3; ++k) previous = kYaw * vg::so3Exp(vg::matchRow(previous, current) * skew) * current;
    m.previous.push_back((previous / previous.z() + Eigen::Vector3d(noise(rng), noise(rng), 0.0)).normalized());
    m.current.push_back(current);
  }
  vg::ResidualCorrelation correlation;
  const Eigen::Vector3d none = Eigen::Vector3d::Zero();
  EXPECT_GT(correlation.compute(m.previous, m.current, kYaw, none, 1.0 / kFocal, kGate), 0.5);
  EXPECT_LT(std::abs(correlation.compute(m.previous, m.current, kYaw, none, 1.0 / kFocal, kGate, skew)), 0.12);
}

TEST(ResidualCorrelation, TooFewPairsOrBadInputIsNotJudged) {
  const Matches few = makeMatches(kYaw, 0.3, [](double, double) { return Eigen::Vector2d::Zero(); }, 20);
  vg::ResidualCorrelation correlation;
  EXPECT_TRUE(std::isnan(correlation.compute(few.previous, few.current, kYaw, Eigen::Vector3d::Zero(), 1.0 / kFocal, kGate)));
  Matches m = makeMatches(kYaw, 0.3, [](double, double) { return Eigen::Vector2d::Zero(); });
  m.previous.pop_back();
  EXPECT_TRUE(std::isnan(correlation.compute(m.previous, m.current, kYaw, Eigen::Vector3d::Zero(), 1.0 / kFocal, kGate)));
  m.current.pop_back();
  EXPECT_TRUE(std::isnan(correlation.compute(m.previous, m.current, kYaw, Eigen::Vector3d::Zero(), 0.0, kGate)));
  // Wrong matches (beyond three gates) stay out: a few of them do not change the verdict.
  for (size_t i = 0; i < m.previous.size(); i += 10) m.previous[i] = Eigen::Vector3d(0.3, 0.1, 1.0).normalized();
  const double c = correlation.compute(m.previous, m.current, kYaw, Eigen::Vector3d::Zero(), 1.0 / kFocal, kGate);
  EXPECT_LT(std::abs(c), 0.12);
}

TEST(CalibrationFitMonitor, JudgesAFullWindowByItsMedian) {
  vg::CalibrationFitMonitor monitor;
  for (size_t k = 0; k + 1 < vg::kFitWindowFrames; ++k) monitor.add(0.7);
  monitor.add(std::numeric_limits<double>::quiet_NaN());  // not judged: not counted
  EXPECT_FALSE(monitor.mismatch()) << "judged before the window is full";
  monitor.add(0.7);
  EXPECT_TRUE(monitor.mismatch());
  EXPECT_NE(monitor.describe().find("correlation 0.7 over the last 20 frames"), std::string::npos) << monitor.describe();
  EXPECT_NE(monitor.describe().find("camera_info's distortion or intrinsics may not fit the images"), std::string::npos);
  // Below the bound for more than half the window: it fits again.
  for (size_t k = 0; k <= vg::kFitWindowFrames / 2; ++k) monitor.add(0.1);
  EXPECT_FALSE(monitor.mismatch());
  for (size_t k = 0; k < vg::kFitWindowFrames; ++k) monitor.add(0.7);
  EXPECT_TRUE(monitor.mismatch());
  monitor.reset();
  EXPECT_FALSE(monitor.mismatch());
  EXPECT_TRUE(std::isnan(monitor.median()));
}

namespace {

/// Rendered views of the hand-held room turning right by 1 deg per frame and back, 10 Hz.
const std::vector<cv::Mat>& turningViews(const vg::RenderSettings& scene) {
  static const std::vector<cv::Mat> views = [&scene] {
    std::vector<cv::Mat> out;
    for (int k = 0; k < 40; ++k) {
      const double yaw = k < 20 ? k : 40 - k;
      out.push_back(vg::renderView(
          scene, Eigen::AngleAxisd(yaw * vg::kDegToRad, Eigen::Vector3d::UnitY()).toRotationMatrix(),
          Eigen::Vector3d::Zero()));
    }
    return out;
  }();
  return views;
}

/// The pipeline's results over the views.
std::vector<vg::FrameResult> results(vg::VisualGyro* gyro, const std::vector<cv::Mat>& views, double t0) {
  std::vector<vg::FrameResult> out;
  for (size_t k = 0; k < views.size(); ++k) out.push_back(gyro->processFrame(views[k], t0 + 0.1 * k));
  return out;
}

}  // namespace

TEST(CalibrationFit, PipelineInflatesTheCovarianceWhileTheCalibrationDoesNotFit) {
  const vg::RenderSettings scene = vg::test::handheldRoom(320, 240, 250.0);
  const std::vector<cv::Mat>& views = turningViews(scene);
  // The right camera: never a mismatch.
  vg::VisualGyro right(vg::test::cameraOf(scene), vg::test::cpuSettings());
  for (const vg::FrameResult& r : results(&right, views, 0.0)) EXPECT_TRUE(r.calibration_mismatch.empty());
  // A plumb_bob k1 = 0.3 the images do not have (plausible by itself: calibrationProblem passes
  // it). Every estimate is valid; from the first full window on, each says why the calibration does
  // not fit and its covariance is inflated.
  const vg::CameraModel wrong(250.0, 250.0, 159.5, 119.5, 320, 240, vg::DistortionModel::kPlumbBob, {0.3, 0.0, 0.0, 0.0});
  ASSERT_EQ(vg::calibrationProblem(wrong), "");
  vg::VisualGyro gyro(wrong, vg::test::cpuSettings());
  const std::vector<vg::FrameResult> got = results(&gyro, views, 0.0);
  int mismatched = 0;
  for (size_t k = 1; k < got.size(); ++k) {
    EXPECT_EQ(got[k].status, vg::FrameStatus::kValid) << "frame " << k;
    if (k <= vg::kFitWindowFrames - 1) EXPECT_TRUE(got[k].calibration_mismatch.empty()) << "frame " << k;
    mismatched += !got[k].calibration_mismatch.empty();
  }
  EXPECT_GE(mismatched, static_cast<int>(got.size() - vg::kFitWindowFrames - 2));
  const vg::FrameResult& last = got.back();
  EXPECT_GT(last.residual_correlation, vg::kFitMismatchCorrelation);
  EXPECT_NE(last.calibration_mismatch.find("may not fit the images"), std::string::npos) << last.calibration_mismatch;
  // The same matches through an estimator alone: the covariance without the check.
  auto estimator = vg::createRotationEstimator(vg::test::cpuSettings().estimator);
  estimator->setRefinedPositions(vg::test::cpuSettings().front_end.subpixel_refinement);
  estimator->setMatchFootprint(vg::matchFootprint(wrong));
  const vg::RotationResult alone = estimator->estimate(last.previous_bearings, last.current_bearings);
  ASSERT_TRUE(alone.valid());
  // At least (1 + 0.5) / (1 - 0.5) = 3 from a median correlation of kFitMismatchCorrelation; the
  // estimator alone draws other triples (seed, no prior), so its covariance differs a little.
  const double ratio = last.rotation.covariance.trace() / alone.covariance.trace();
  EXPECT_GE(ratio, 2.5) << "covariance not inflated";
  EXPECT_LE(ratio, 1.2 * vg::kMaxFitInflation);
  // A new camera model starts the check afresh.
  gyro.setCamera(vg::test::cameraOf(scene));
  for (const vg::FrameResult& r : results(&gyro, views, 30.0)) EXPECT_TRUE(r.calibration_mismatch.empty());
}

TEST(CalibrationFitMonitor, InflationIsTheEffectiveSampleSizeRatio) {
  vg::CalibrationFitMonitor monitor;
  for (size_t k = 0; k < vg::kFitWindowFrames; ++k) monitor.add(0.6);
  EXPECT_NEAR(monitor.covarianceInflation(), 1.6 / 0.4, 1e-12);
  vg::CalibrationFitMonitor strong;
  for (size_t k = 0; k < vg::kFitWindowFrames; ++k) strong.add(0.99);
  EXPECT_DOUBLE_EQ(strong.covarianceInflation(), vg::kMaxFitInflation);
  vg::CalibrationFitMonitor fits;
  for (size_t k = 0; k < vg::kFitWindowFrames; ++k) fits.add(0.2);
  EXPECT_DOUBLE_EQ(fits.covarianceInflation(), 1.0);
}
