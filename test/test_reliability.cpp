// Plausibility before publishing and bad input, for the pipeline and for `evaluate` on malformed
// folders (made here from a small rendered sequence). Each case is a row of the bad-input
// table in doc/reliability.md; the ROS rows are in test/ros/test_reliability_ros.cpp.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <opencv2/imgcodecs.hpp>

#include "test_support.h"
#include "visual_gyro/renderer.h"
#include "visual_gyro/rotation_estimator.h"
#include "visual_gyro/visual_gyro.h"

namespace vg = visual_gyro;
namespace fs = std::filesystem;

namespace {

constexpr double kDeg = M_PI / 180.0;

vg::RenderSettings scene() {
  vg::RenderSettings s = vg::test::handheldRoom(320, 240, 250.0);
  s.noise_sigma = 1.0;
  return s;
}

cv::Mat view(double yaw_deg) {
  return vg::renderView(scene(), Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitY()).toRotationMatrix(),
                        Eigen::Vector3d::Zero());
}

vg::CameraModel camera() { return vg::test::cameraOf(scene()); }

vg::VisualGyroSettings cpu() { return vg::test::cpuSettings(); }

bool contains(const std::string& text, const std::string& needle) { return text.find(needle) != std::string::npos; }

// The fields of a CSV line split at every comma (quoted fields are not read whole).
std::vector<std::string> split(const std::string& line, char separator) {
  std::vector<std::string> fields(1);
  for (const char c : line) {
    if (c == separator) fields.emplace_back();
    else fields.back() += c;
  }
  return fields;
}

}  // namespace

TEST(Plausibility, StepsBelowMinDtAreSkippedAndNeverValid) {
  vg::VisualGyro gyro(camera(), cpu());
  const cv::Mat a = view(0.0), b = view(1.0), c = view(2.0);
  ASSERT_EQ(gyro.processFrame(a, 10.0).status, vg::FrameStatus::kFirstFrame);
  for (const double step : {1e-6, 3e-9}) {  // 1 us and 3 ns apart
    const vg::FrameResult r = gyro.processFrame(b, 10.0 + step);
    EXPECT_FALSE(r.hasEstimate()) << "a " << step << " s step gave an estimate";
    EXPECT_TRUE(r.skipped());
    EXPECT_EQ(r.status, vg::FrameStatus::kTimeStepTooSmall) << r.reason;
    EXPECT_TRUE(r.angular_velocity.isZero());
  }
  // The skipped frames left the state alone: the next frame pairs with the one at 10 s.
  const vg::FrameResult r = gyro.processFrame(c, 10.1);
  ASSERT_TRUE(r.hasEstimate()) << vg::frameStatusName(r.status) << ": " << r.reason;
  EXPECT_NEAR(r.dt, 0.1, 1e-12);
  EXPECT_NEAR(r.rotation.yaw, 2.0 * kDeg, 0.1 * kDeg);
}

TEST(Plausibility, RateAboveMaxRateIsInvalidWithItsReason) {
  vg::VisualGyroSettings s = cpu();
  s.max_rate_dps = 15.0;  // the views turn 1 deg per 0.05 s = 20 deg/s
  vg::VisualGyro gyro(camera(), s);
  gyro.processFrame(view(0.0), 1.0);
  vg::FrameResult r = gyro.processFrame(view(1.0), 1.05);
  EXPECT_FALSE(r.hasEstimate());
  EXPECT_FALSE(r.rotation.valid());
  EXPECT_EQ(r.status, vg::FrameStatus::kImplausibleRate) << r.reason;
  EXPECT_TRUE(contains(r.reason, "above max_rate_dps")) << r.reason;
  EXPECT_TRUE(r.angular_velocity.isZero());
  EXPECT_TRUE(r.rotation.rotation.isIdentity());
  // The same turn under the default limit is valid.
  s.max_rate_dps = vg::VisualGyroSettings().max_rate_dps;
  gyro.setSettings(s);
  r = gyro.processFrame(view(2.0), 1.10);
  ASSERT_TRUE(r.hasEstimate()) << vg::frameStatusName(r.status) << ": " << r.reason;
  EXPECT_NEAR(r.angular_velocity.norm(), 20.0 * kDeg, 1.0 * kDeg);
  EXPECT_EQ(vg::checkRatePlausible(Eigen::Vector3d(0, 0.01, 0), 1e-6, vg::VisualGyroSettings()).empty(), false);
}

TEST(Plausibility, FrozenCameraIsFlaggedAndNeverValid) {
  vg::VisualGyro gyro(camera(), cpu());
  const cv::Mat a = view(0.0);
  gyro.processFrame(a, 1.0);
  // A driver repeating the frame with new stamps.
  for (int k = 1; k <= 3; ++k) {
    const vg::FrameResult r = gyro.processFrame(a.clone(), 1.0 + 0.05 * k);
    EXPECT_EQ(r.status, vg::FrameStatus::kFrozenImage) << r.reason;
    EXPECT_FALSE(r.hasEstimate());
    EXPECT_FALSE(r.skipped());
    EXPECT_NEAR(r.dt, 0.05 * k, 1e-12) << "the repeated frame must keep the first one's stamp";
  }
  // The camera comes back: the estimate spans from the last real image.
  const vg::FrameResult r = gyro.processFrame(view(3.0), 1.2);
  ASSERT_TRUE(r.hasEstimate()) << vg::frameStatusName(r.status) << ": " << r.reason;
  EXPECT_NEAR(r.dt, 0.2, 1e-12);
  EXPECT_NEAR(r.rotation.yaw, 3.0 * kDeg, 0.1 * kDeg);
}

TEST(Plausibility, SettingsOfTheirOwnAreValidated) {
  vg::VisualGyroSettings s = cpu();
  s.min_dt = -1.0;
  EXPECT_FALSE(vg::validateVisualGyroSettings(s).empty());
  EXPECT_THROW(vg::VisualGyro(camera(), s), std::invalid_argument);
  s = cpu();
  s.max_rate_dps = 0.0;
  EXPECT_FALSE(vg::validateVisualGyroSettings(s).empty());
  s.max_rate_dps = NAN;
  EXPECT_FALSE(vg::validateVisualGyroSettings(s).empty());
  EXPECT_EQ(vg::validateVisualGyroSettings(cpu()), "");
}

TEST(Plausibility, TinyBinsAreRefusedNotCastOutOfRange) {
  // 2 * 6 / 1e-12 bins is far beyond int: refused by name, with no undefined conversion.
  vg::EstimatorSettings e;
  e.rotation_bin_deg = 1e-12;
  EXPECT_TRUE(contains(vg::validateSettings(e), "rotation_bin_deg must be in [0.01, 10] deg")) << vg::validateSettings(e);
  e = vg::EstimatorSettings();
  e.yaw_bin_deg = 1e-300;
  EXPECT_TRUE(contains(vg::validateSettings(e), "yaw_bin_deg must be in [0.001, 10] deg")) << vg::validateSettings(e);
}

TEST(Calibration, ImplausibleCalibrationIsNamed) {
  EXPECT_EQ(vg::calibrationProblem(camera()), "");
  // Principal point far outside the image.
  EXPECT_TRUE(contains(vg::calibrationProblem(vg::CameraModel(250, 250, 5000, 119.5, 320, 240)), "principal point"));
  EXPECT_TRUE(contains(vg::calibrationProblem(vg::CameraModel(250, 250, 159.5, -40, 320, 240)), "principal point"));
  // Focal lengths implausible for the size, or wildly different.
  EXPECT_TRUE(contains(vg::calibrationProblem(vg::CameraModel(1, 1, 159.5, 119.5, 320, 240)), "focal length"));
  EXPECT_TRUE(contains(vg::calibrationProblem(vg::CameraModel(1e6, 1e6, 159.5, 119.5, 320, 240)), "focal length"));
  EXPECT_TRUE(contains(vg::calibrationProblem(vg::CameraModel(250, 2000, 159.5, 119.5, 320, 240)), "fy / fx"));
  // Barrel distortion that folds back inside the image (k1 = -1: the radius peaks at r = 0.58).
  const vg::CameraModel folded(250, 250, 159.5, 119.5, 320, 240, vg::DistortionModel::kPlumbBob, {-1.0, 0, 0, 0});
  EXPECT_TRUE(contains(vg::calibrationProblem(folded), "fold")) << vg::calibrationProblem(folded);
  EXPECT_THROW(vg::VisualGyro(folded, cpu()), std::invalid_argument);
  // Real lenses pass: EuRoC's radial-tangential and a fisheye.
  EXPECT_EQ(vg::calibrationProblem(vg::CameraModel(458.654, 457.296, 367.215, 248.375, 752, 480,
                                                   vg::DistortionModel::kPlumbBob,
                                                   {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05})),
            "");
  EXPECT_EQ(vg::calibrationProblem(vg::CameraModel(190.97, 190.97, 254.93, 256.89, 512, 512,
                                                   vg::DistortionModel::kEquidistant,
                                                   {0.0034823, 0.0007150, -0.0020532, 0.0002029})),
            "");
  vg::VisualGyro gyro(camera(), cpu());
  EXPECT_THROW(gyro.setCamera(vg::CameraModel(250, 250, 5000, 119.5, 320, 240)), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// evaluate on malformed folders
// ---------------------------------------------------------------------------------------------

class EvaluateBadInput : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = vg::test::makeTempDir("bad_input");
    int status = 0;
    const std::string out = vg::test::runCommand(std::string(VISUAL_GYRO_RENDER) +
                                                     " --preset handheld --frames 6 --width 320 --height 240 "
                                                     "--focal 250 --rate 10 --out " + root_ + "/good",
                                                 &status);
    ASSERT_EQ(status, 0) << out;
  }
  static void TearDownTestSuite() { fs::remove_all(root_); }

  /// A copy of the good folder under `name`.
  static std::string copy(const std::string& name) {
    const fs::path to = fs::path(root_) / name;
    fs::remove_all(to);
    fs::copy(fs::path(root_) / "good", to, fs::copy_options::recursive);
    return to.string();
  }
  static void write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }
  static std::string evaluate(const std::string& args, int* status) {
    return vg::test::runCommand(std::string(VISUAL_GYRO_EVALUATE) + " " + args + " --backend cpu --quiet", status);
  }

  static std::string root_;
};
std::string EvaluateBadInput::root_;

TEST_F(EvaluateBadInput, GoodFolderPasses) {
  int status = -1;
  const std::string out = evaluate(root_ + "/good", &status);
  EXPECT_EQ(status, 0) << out;
  EXPECT_EQ(vg::test::jsonNumber(out, "invalid"), 0.0) << out;
}

TEST_F(EvaluateBadInput, MovingRegionIsReportedAndItsAngleNeedsIt) {
  int status = -1;
  std::string out = evaluate(root_ + "/good --moving-region 0.3 --moving-deg 1.5", &status);
  EXPECT_EQ(status, 0) << out;
  EXPECT_EQ(vg::test::jsonNumber(out, "moving_region"), 0.3) << out;
  EXPECT_EQ(vg::test::jsonNumber(out, "moving_deg"), 1.5) << out;
  EXPECT_TRUE(contains(out, "30 % of the matches moving by 1.50 deg")) << out;
  out = evaluate(root_ + "/good --moving-deg 1.5", &status);
  EXPECT_EQ(status, 2) << out;
  EXPECT_TRUE(contains(out, "--moving-deg needs --moving-region")) << out;
}

TEST_F(EvaluateBadInput, MicrosecondStepsMakeTheFolderUnusable) {
  const std::string dir = copy("us_steps");
  write(dir + "/times.txt", "0.0\n0.000001\n0.000002\n0.000003\n0.000004\n0.000005\n");
  int status = 0;
  const std::string out = evaluate(dir, &status);
  EXPECT_EQ(status, 1) << out;
  EXPECT_TRUE(contains(out, "below min_dt")) << out;
  EXPECT_FALSE(contains(out, "mean_rate_dps")) << "a rate was reported: " << out;
}

TEST_F(EvaluateBadInput, SomeShortStepsAreSkippedAndCounted) {
  const std::string dir = copy("short_step");
  write(dir + "/times.txt", "0.0\n0.1\n0.1000001\n0.3\n0.4\n0.5\n");
  int status = -1;
  const std::string out = evaluate(dir, &status);
  EXPECT_EQ(status, 0) << out;
  EXPECT_TRUE(contains(out, "1 frame(s) skipped")) << out;
  EXPECT_EQ(vg::test::jsonNumber(out, "frames"), 4.0) << out;
}

TEST_F(EvaluateBadInput, FrozenFramesAreCountedInvalid) {
  const std::string dir = copy("frozen");
  fs::copy_file(dir + "/image_l/000001.png", dir + "/image_l/000002.png", fs::copy_options::overwrite_existing);
  int status = -1;
  const std::string out = evaluate(dir + " --method vote,essential5", &status);
  EXPECT_EQ(status, 0) << out;
  EXPECT_TRUE(contains(out, "camera frozen?")) << out;
  // Both methods: exactly the frozen pair is invalid.
  size_t lines = 0;
  for (size_t at = out.find("{\"dataset\""); at != std::string::npos; at = out.find("{\"dataset\"", at + 1)) {
    EXPECT_EQ(vg::test::jsonNumber(out.substr(at), "invalid"), 1.0) << out;
    ++lines;
  }
  EXPECT_EQ(lines, 2u) << out;
}

TEST_F(EvaluateBadInput, ImplausibleCalibrationMakesTheFolderUnusable) {
  const std::string dir = copy("bad_calib");
  write(dir + "/calib.txt", "P0: 250 0 5000 0 0 250 119.5 0 0 0 1 0\n");
  int status = 0;
  std::string out = evaluate(dir, &status);
  EXPECT_EQ(status, 1) << out;
  EXPECT_TRUE(contains(out, "principal point")) << out;
  write(dir + "/calib.txt", "P0: 2 0 159.5 0 0 2 119.5 0 0 0 1 0\n");
  out = evaluate(dir, &status);
  EXPECT_EQ(status, 1) << out;
  EXPECT_TRUE(contains(out, "focal length")) << out;
  // Inside the image but at its corner: a K that does not belong to these images.
  write(dir + "/calib.txt", "P0: 250 0 319 0 0 250 239 0 0 0 1 0\n");
  out = evaluate(dir, &status);
  EXPECT_EQ(status, 1) << out;
  EXPECT_TRUE(contains(out, "implausible calibration: principal point (319, 239) lies at 99.8 % / 99.8 %")) << out;
  EXPECT_FALSE(contains(out, "mean_rate_dps")) << "a rate was reported: " << out;
}

TEST_F(EvaluateBadInput, ImagesSmallerThanThePatchAreNamed) {
  const std::string dir = (fs::path(root_) / "tiny").string();
  fs::create_directories(dir + "/image_l");
  for (int k = 0; k < 3; ++k) {
    cv::Mat img(20, 24, CV_8UC1);
    cv::randu(img, 0, 255);
    cv::imwrite(dir + "/image_l/00000" + std::to_string(k) + ".png", img);
  }
  write(dir + "/calib.txt", "P0: 20 0 11.5 0 0 20 9.5 0 0 0 1 0\n");
  int status = 0;
  const std::string out = evaluate(dir, &status);
  EXPECT_EQ(status, 1) << out;
  EXPECT_TRUE(contains(out, "smaller than the descriptor patch")) << out;
}

TEST_F(EvaluateBadInput, UnclosedYamlListIsNamed) {
  const std::string dir = (fs::path(root_) / "euroc_unclosed").string();
  fs::create_directories(dir + "/cam0/data");
  write(dir + "/cam0/data.csv", "#timestamp [ns],filename\n1000,a.png\n2000,b.png\n");
  write(dir + "/cam0/sensor.yaml",
        "intrinsics: [250, 250, 159.5, 119.5\nresolution: [320, 240]\ndistortion_model: none\n"
        "T_BS:\n  data: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]\n");
  int status = 0;
  const std::string out = evaluate(dir, &status);
  EXPECT_EQ(status, 1) << out;
  EXPECT_TRUE(contains(out, "not closed")) << out;
  EXPECT_FALSE(contains(out, "not a number")) << out;
}

TEST_F(EvaluateBadInput, OutOfRangeOptionsAreNamed) {
  int status = 0;
  std::string out = evaluate(root_ + "/good --set rotation_bin_deg=1e-12", &status);
  EXPECT_EQ(status, 2) << out;
  EXPECT_TRUE(contains(out, "rotation_bin_deg must be in [0.01, 10] deg")) << out;
  out = evaluate(root_ + "/good --set yaw_bin_deg=1e-300 --method paper", &status);
  EXPECT_EQ(status, 2) << out;
  EXPECT_TRUE(contains(out, "yaw_bin_deg must be in [0.001, 10] deg")) << out;
  out = evaluate(root_ + "/good --hypotheses 99999999999", &status);
  EXPECT_EQ(status, 2) << out;
  EXPECT_TRUE(contains(out, "1..10000000")) << out;
  EXPECT_FALSE(contains(out, "must be positive")) << out;
  out = evaluate(root_ + "/good --set min_dt=-1", &status);
  EXPECT_EQ(status, 2) << out;
  EXPECT_TRUE(contains(out, "min_dt")) << out;
  out = evaluate(root_ + "/good --gain-jitter 1", &status);
  EXPECT_EQ(status, 2) << out;
  EXPECT_TRUE(contains(out, "--gain-jitter")) << out;
  out = evaluate(root_ + "/good --gain-jitter 0.2 --stuck-pixels 30", &status);
  EXPECT_EQ(status, 0) << out;
  EXPECT_EQ(vg::test::jsonNumber(out, "gain_jitter"), 0.2) << out;
  EXPECT_EQ(vg::test::jsonNumber(out, "stuck_pixels"), 30.0) << out;
  out = evaluate(root_ + "/good --stuck-pixels -1", &status);
  EXPECT_EQ(status, 2) << out;
  const std::string csv = root_ + "/implausible.csv";
  out = evaluate(root_ + "/good --set max_rate_dps=5 --csv " + csv, &status);  // the views turn faster
  EXPECT_EQ(status, 0) << out;
  EXPECT_EQ(vg::test::jsonNumber(out, "invalid"), 5.0) << out;
  // As in the pipeline, an implausible rate is no prior for the next pair.
  std::ifstream rows(csv);
  std::string header, row;
  ASSERT_TRUE(std::getline(rows, header));
  const std::vector<std::string> columns = split(header, ',');
  const size_t prior_used = std::find(columns.begin(), columns.end(), "prior_used") - columns.begin();
  ASSERT_LT(prior_used, columns.size()) << header;
  int judged = 0;
  while (std::getline(rows, row)) {
    const std::vector<std::string> fields = split(row, ',');
    ASSERT_GT(fields.size(), prior_used) << row;
    EXPECT_EQ(fields[prior_used], "0") << row;
    ++judged;
  }
  EXPECT_EQ(judged, 5);
}
