// Sequence loaders: the shared KITTI and EuRoC folders, gyro integration on a made-up EuRoC
// folder, and malformed inputs.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

#include "test_support.h"
#include "visual_gyro/sequence.h"

namespace visual_gyro {
namespace {

namespace fs = std::filesystem;
constexpr double kDeg = M_PI / 180.0;

double yawOf(const Eigen::Matrix3d& R) { return std::atan2(R(0, 2), R(2, 2)); }

/// Expects loadSequence(folder) to throw std::runtime_error whose message contains `needle`.
void expectLoadError(const std::string& folder, const std::string& needle) {
  try {
    loadSequence(folder);
    ADD_FAILURE() << "no exception for " << folder << " (expected one naming '" << needle << "')";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
        << "message '" << e.what() << "' does not name '" << needle << "'";
  }
}

void writeFile(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path) << text;
}

void writeImage(const fs::path& path) {
  fs::create_directories(path.parent_path());
  ASSERT_TRUE(cv::imwrite(path.string(), cv::Mat(12, 16, CV_8UC1, cv::Scalar(90))));
}

TEST(SharedSequence, KittiTurn) {
  std::string why;
  const std::string path = test::sharedSequence("kitti_turn", &why);
  if (path.empty()) GTEST_SKIP() << why;
  const Sequence seq = loadSequence(path);
  EXPECT_EQ(seq.name, "kitti_turn");
  EXPECT_EQ(seq.layout, "kitti");
  ASSERT_EQ(seq.image_paths.size(), 51u);
  ASSERT_EQ(seq.stamps.size(), 51u);
  EXPECT_DOUBLE_EQ(seq.stamps[10], 1.0);
  // This folder's calib.txt holds 718.856 (KITTI sequence 00-02 intrinsics), not the 707.0912 of
  // kitti_straight that the data README quotes for both.
  EXPECT_NEAR(seq.camera.fx(), 718.856, 1e-9);
  EXPECT_NEAR(seq.camera.fy(), 718.856, 1e-9);
  EXPECT_NEAR(seq.camera.cx(), 607.1928, 1e-9);
  EXPECT_NEAR(seq.camera.cy(), 185.2157, 1e-9);
  EXPECT_EQ(seq.camera.width(), 1241);
  EXPECT_EQ(seq.camera.height(), 376);
  EXPECT_EQ(seq.camera.distortionModel(), DistortionModel::kNone);
  ASSERT_TRUE(seq.hasPoses());
  EXPECT_FALSE(seq.hasGyro());
  double yaw_sum = 0, yaw_max = 0;
  for (size_t k = 1; k < seq.image_paths.size(); ++k) {
    Eigen::Matrix3d R;
    ASSERT_TRUE(seq.trueRotation(k, &R));
    EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-9);
    yaw_sum += yawOf(R);
    yaw_max = std::max(yaw_max, std::abs(yawOf(R)));
    Eigen::Vector3d omega;
    ASSERT_TRUE(seq.trueAngularVelocity(k, &omega));
    EXPECT_NEAR(omega.norm() * 0.1, Eigen::AngleAxisd(R).angle(), 1e-12);
  }
  EXPECT_NEAR(yaw_sum / kDeg, 97.9, 0.3);  // a right turn: positive yaw about +y (down)
  EXPECT_NEAR(yaw_max / kDeg, 2.74, 0.05);
  // The car ends ~40 m to the right of where it started.
  EXPECT_GT(seq.positions.back().x(), 30.0);
  Eigen::Matrix3d R;
  EXPECT_FALSE(seq.trueRotation(0, &R));
  EXPECT_FALSE(seq.trueRotation(51, &R));
}

TEST(SharedSequence, KittiStraight) {
  std::string why;
  const std::string path = test::sharedSequence("kitti_straight", &why);
  if (path.empty()) GTEST_SKIP() << why;
  const Sequence seq = loadSequence(path);
  ASSERT_EQ(seq.image_paths.size(), 51u);
  EXPECT_NEAR(seq.camera.fx(), 707.0912, 1e-9);
  EXPECT_EQ(seq.camera.width(), 1226);
  EXPECT_EQ(seq.camera.height(), 370);
  ASSERT_TRUE(seq.hasPoses());
  for (size_t k = 1; k < seq.image_paths.size(); ++k) {
    Eigen::Matrix3d R;
    ASSERT_TRUE(seq.trueRotation(k, &R));
    EXPECT_LT(Eigen::AngleAxisd(R).angle() / kDeg, 0.25) << "frame " << k;
  }
}

TEST(SharedSequence, EurocStatic) {
  std::string why;
  const std::string path = test::sharedSequence("euroc_v101_static", &why);
  if (path.empty()) GTEST_SKIP() << why;
  const Sequence seq = loadSequence(path);
  EXPECT_EQ(seq.name, "euroc_v101_static");
  EXPECT_EQ(seq.layout, "euroc");
  EXPECT_EQ(seq.truth, "gyro");
  ASSERT_EQ(seq.image_paths.size(), 95u);
  ASSERT_EQ(seq.stamps.size(), 95u);
  EXPECT_TRUE(fs::is_regular_file(seq.image_paths.front())) << seq.image_paths.front();
  EXPECT_NEAR(seq.stamps.front(), 1403715273.262142976, 1e-6);
  EXPECT_NEAR(seq.stamps[1] - seq.stamps[0], 0.05, 1e-6);
  EXPECT_EQ(seq.camera.width(), 752);
  EXPECT_EQ(seq.camera.height(), 480);
  EXPECT_DOUBLE_EQ(seq.camera.fx(), 458.654);
  EXPECT_DOUBLE_EQ(seq.camera.fy(), 457.296);
  EXPECT_DOUBLE_EQ(seq.camera.cx(), 367.215);
  EXPECT_DOUBLE_EQ(seq.camera.cy(), 248.375);
  EXPECT_EQ(seq.camera.distortionModel(), DistortionModel::kPlumbBob);
  const std::vector<double> expected = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  ASSERT_EQ(seq.camera.distortion().size(), 4u);
  for (size_t i = 0; i < 4; ++i) EXPECT_DOUBLE_EQ(seq.camera.distortion()[i], expected[i]);
  EXPECT_EQ(seq.camera.validate(), "");
  ASSERT_TRUE(seq.hasGyro());
  EXPECT_FALSE(seq.hasPoses());
  EXPECT_GT(seq.gyro.size(), 1000u);
  const Eigen::Matrix3d& R_bs = seq.body_from_camera;
  EXPECT_LT((R_bs.transpose() * R_bs - Eigen::Matrix3d::Identity()).norm(), 1e-9);
  EXPECT_NEAR(R_bs.determinant(), 1.0, 1e-9);
  EXPECT_NEAR(R_bs(0, 1), -0.999880929698, 1e-6);  // camera y (down) ~ body -x
  EXPECT_NEAR(R_bs(1, 0), 0.999557249008, 1e-6);

  // The drone stands still: the gyro reads its bias, and so does the "truth" (not removed). The
  // bias is the mean reading while the frames were taken (the file runs on for a second after the
  // last frame, when the drone starts to move).
  Eigen::Vector3d bias = Eigen::Vector3d::Zero();
  int samples = 0;
  for (const auto& s : seq.gyro) {
    if (s.stamp < seq.stamps.front() || s.stamp > seq.stamps.back()) continue;
    bias += s.angular_velocity;
    ++samples;
  }
  ASSERT_GT(samples, 900);
  bias /= samples;
  const Eigen::Vector3d bias_camera = R_bs.transpose() * bias;
  EXPECT_GT(bias.norm(), 0.05);
  double total_deg = 0;
  Eigen::Vector3d mean_omega = Eigen::Vector3d::Zero();
  for (size_t k = 1; k < seq.image_paths.size(); ++k) {
    Eigen::Matrix3d R;
    ASSERT_TRUE(seq.trueRotation(k, &R)) << "frame " << k;
    const Eigen::AngleAxisd aa(R);
    EXPECT_LT(aa.angle() / kDeg, 0.5) << "frame " << k;
    total_deg += aa.angle() / kDeg;
    Eigen::Vector3d omega;
    ASSERT_TRUE(seq.trueAngularVelocity(k, &omega));
    // Per frame the ADIS16448's noise (and the rotors' vibration) moves it by up to ~0.04 rad/s.
    EXPECT_LT((omega - bias_camera).norm(), 0.05) << "frame " << k << ": " << omega.transpose();
    mean_omega += omega / static_cast<double>(seq.image_paths.size() - 1);
    // The integrated rotation agrees with the mean rate over the interval.
    const double dt = seq.stamps[k] - seq.stamps[k - 1];
    EXPECT_LT((aa.angle() * aa.axis() - omega * dt).norm(), 1e-4);
  }
  EXPECT_LT((mean_omega - bias_camera).norm(), 2e-3) << mean_omega.transpose() << " vs " << bias_camera.transpose();
  std::printf("euroc_v101_static: gyro bias (camera frame) %.4f %.4f %.4f rad/s, %.2f deg of 'rotation' over %zu "
              "frames\n",
              bias_camera.x(), bias_camera.y(), bias_camera.z(), total_deg, seq.image_paths.size() - 1);
}

/// A tiny EuRoC folder with a known T_BS and gyro; checks the integration against closed forms.
TEST(Sequence, EurocGyroIntegration) {
  const fs::path root = fs::path(test::makeTempDir("seq_euroc")) / "made_up";
  // Three frames at 2.5, 52.5 and 102.5 ms (+ 100 s), between the gyro's samples, which run at
  // 200 Hz from -20 ms to 120 ms.
  std::string csv = "#timestamp [ns],filename\n";
  for (int k = 0; k < 3; ++k) {
    const long long ns = 100002500000LL + k * 50000000LL;
    csv += std::to_string(ns) + "," + std::to_string(ns) + ".png\r\n";  // CRLF too
    writeImage(root / "cam0" / "data" / (std::to_string(ns) + ".png"));
  }
  writeFile(root / "cam0" / "data.csv", csv);
  // T_BS: camera z = body x, camera x = body -y, camera y = body -z (a forward-looking camera).
  writeFile(root / "cam0" / "sensor.yaml",
            "%YAML:1.0\nsensor_type: camera\nT_BS:\n  cols: 4\n  rows: 4\n  data: [0.0, 0.0, 1.0, 0.1,\n"
            "         -1.0, 0.0, 0.0, 0.0,\n         0.0, -1.0, 0.0, 0.0,\n         0.0, 0.0, 0.0, 1.0]\n"
            "rate_hz: 20\nresolution: [16, 12]\ncamera_model: pinhole\n"
            "intrinsics: [10.0, 11.0, 7.5, 5.5] #fu, fv, cu, cv\n"
            "distortion_model: radial-tangential\ndistortion_coefficients: [0.01, -0.002, 0.0, 0.0]\n");
  // Body rate: constant 0.5 rad/s about body z, plus a ramp about body x: 2 t rad/s.
  std::string imu = "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n";
  for (int i = -4; i <= 24; ++i) {
    const double t = i * 0.005;
    const long long ns = 100000000000LL + i * 5000000LL;
    char line[256];
    std::snprintf(line, sizeof(line), "%lld,%.17g,0,0.5,0,0,9.81\n", ns, 2.0 * t);
    imu += line;
  }
  writeFile(root / "imu0" / "data.csv", imu);

  const Sequence seq = loadSequence(root.string());
  EXPECT_EQ(seq.name, "made_up");
  ASSERT_EQ(seq.image_paths.size(), 3u);
  EXPECT_EQ(seq.camera.width(), 16);
  EXPECT_EQ(seq.camera.distortionModel(), DistortionModel::kPlumbBob);
  ASSERT_EQ(seq.gyro.size(), 29u);
  Eigen::Matrix3d R_bs;
  R_bs << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  EXPECT_LT((seq.body_from_camera - R_bs).norm(), 1e-12);

  // Interval [0.0525, 0.1025] s: body z rate 0.5 -> camera -y; body x ramp -> camera z, mean
  // 2 * 0.0775 (the ends are interpolated between samples).
  Eigen::Vector3d omega;
  ASSERT_TRUE(seq.trueAngularVelocity(2, &omega));
  EXPECT_LT((omega - Eigen::Vector3d(0.0, -0.5, 0.155)).norm(), 1e-9) << omega.transpose();
  // The rotation, against a fine integration of the same rate here.
  Eigen::Matrix3d R;
  ASSERT_TRUE(seq.trueRotation(2, &R));
  Eigen::Matrix3d fine = Eigen::Matrix3d::Identity();
  const int steps = 20000;
  for (int s = 0; s < steps; ++s) {
    const double t = 0.0525 + (s + 0.5) * 0.05 / steps;
    const Eigen::Vector3d w_c = R_bs.transpose() * Eigen::Vector3d(2.0 * t, 0.0, 0.5);
    fine = fine * Eigen::AngleAxisd(w_c.norm() * 0.05 / steps, w_c.normalized()).toRotationMatrix();
  }
  // The per-piece midpoint rate differs from the exact solution only at second order (commutator).
  EXPECT_LT((R - fine).norm(), 1e-6);
  EXPECT_GT(Eigen::AngleAxisd(R).angle(), 0.02);
  EXPECT_NEAR(yawOf(R), -0.5 * 0.05, 1e-3);  // rotation about camera -y: negative yaw

  // Frames outside the gyro's span have no truth.
  Sequence cut = seq;
  cut.gyro.resize(10);  // up to 0.025 s
  EXPECT_FALSE(cut.trueRotation(2, &R));
  EXPECT_FALSE(cut.trueAngularVelocity(2, &omega));
  fs::remove_all(root.parent_path());
}

/// A made-up EuRoC folder with ground-truth poses (state_groundtruth_estimate0): the camera
/// rotation between frames is R_BS^T (R_k-1^T R_k) R_BS with R_k slerped at the image stamps,
/// the poses are preferred to the gyro, and frames outside the poses' span have no truth.
TEST(Sequence, EurocGroundTruthPoses) {
  const fs::path root = fs::path(test::makeTempDir("seq_euroc_poses")) / "posed";
  std::string csv = "#timestamp [ns],filename\n";
  for (int k = 0; k < 4; ++k) {  // 100.0025, 100.0525, 100.1025, 100.1525 s
    const long long ns = 100002500000LL + k * 50000000LL;
    csv += std::to_string(ns) + "," + std::to_string(ns) + ".png\n";
    writeImage(root / "cam0" / "data" / (std::to_string(ns) + ".png"));
  }
  writeFile(root / "cam0" / "data.csv", csv);
  writeFile(root / "cam0" / "sensor.yaml",
            "T_BS:\n  cols: 4\n  rows: 4\n  data: [0.0, 0.0, 1.0, 0.1,\n         -1.0, 0.0, 0.0, 0.0,\n"
            "         0.0, -1.0, 0.0, 0.0,\n         0.0, 0.0, 0.0, 1.0]\nresolution: [16, 12]\n"
            "intrinsics: [10.0, 11.0, 7.5, 5.5]\ndistortion_model: none\n");
  // A gyro that says something else: the poses must win.
  writeFile(root / "imu0" / "data.csv", "100000000000,1,1,1\n100200000000,1,1,1\n");
  // Body orientation: yaw about the world z axis at 0.4 rad/s from t = 100 s; position moves
  // along world x at 1 m/s. 200 Hz samples from 100.0 s to 100.12 s (the last image is outside),
  // in EuRoC's full 17-column layout for the first half and its 8-column excerpt for the rest.
  std::string poses = "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
                      "q_RS_z [], v..., b_w..., b_a...\n";
  for (int i = 0; i <= 24; ++i) {
    const double t = i * 0.005;
    const long long ns = 100000000000LL + i * 5000000LL;
    char line[512];
    const double half = 0.5 * 0.4 * t;
    if (i < 12) {
      std::snprintf(line, sizeof(line), "%lld,%.17g,0,0,%.17g,0,0,%.17g,1,0,0,0,0,0,0,0,0\n", ns, t, std::cos(half),
                    std::sin(half));
    } else {
      std::snprintf(line, sizeof(line), "%lld,%.17g,0,0,%.17g,0,0,%.17g\n", ns, t, std::cos(half), std::sin(half));
    }
    poses += line;
  }
  writeFile(root / "state_groundtruth_estimate0" / "data.csv", poses);

  const Sequence seq = loadSequence(root.string());
  EXPECT_EQ(seq.truth, "poses");
  EXPECT_EQ(seq.truth_sigma_deg, Eigen::Vector3d::Constant(kEurocPosesSigmaDeg));
  ASSERT_TRUE(seq.hasPoses());
  ASSERT_EQ(seq.orientations.size(), 4u);
  EXPECT_LT((seq.orientations[0] - Eigen::Matrix3d::Identity()).norm(), 1e-12) << "relative to the first image";
  Eigen::Matrix3d R_bs;
  R_bs << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  // Frame 1 -> 2: a body yaw of 0.4 * 0.05 rad about world (= body) z; in the camera frame
  // R_BS^T Rz R_BS, a rotation about camera -y (body z = camera -y): a left turn, negative yaw.
  Eigen::Matrix3d R;
  ASSERT_TRUE(seq.trueRotation(2, &R));
  const Eigen::Matrix3d expected =
      R_bs.transpose() * Eigen::AngleAxisd(0.4 * 0.05, Eigen::Vector3d::UnitZ()).toRotationMatrix() * R_bs;
  EXPECT_LT((R - expected).norm(), 1e-9);
  EXPECT_NEAR(yawOf(R), -0.02, 1e-9);
  Eigen::Vector3d omega;
  ASSERT_TRUE(seq.trueAngularVelocity(2, &omega));
  EXPECT_LT((omega - Eigen::Vector3d(0, -0.4, 0)).norm(), 1e-6) << omega.transpose();
  // Camera positions (camera -> first camera frame): the body moves 5 cm along world x between
  // frames, with the 10 cm lever arm of T_BS turning with the yaw.
  EXPECT_GT((seq.positions[1] - seq.positions[0]).norm(), 0.04);
  EXPECT_LT((seq.positions[1] - seq.positions[0]).norm(), 0.06);
  // The last image (100.1525 s) is after the last pose (100.12 s): no truth for pair 3.
  EXPECT_FALSE(seq.trueRotation(3, &R));
  EXPECT_FALSE(seq.trueAngularVelocity(3, &omega));

  // A malformed pose line names the file and the line.
  writeFile(root / "state_groundtruth_estimate0" / "data.csv", poses + "100200000000,1,2,3\n");
  expectLoadError(root.string(), "state_groundtruth_estimate0/data.csv:27");
  writeFile(root / "state_groundtruth_estimate0" / "data.csv", "100000000000,0,0,0,2,0,0,0\n100100000000,0,0,0,1,0,0,0\n");
  expectLoadError(root.string(), "quaternion not of unit norm");
  fs::remove_all(root.parent_path());
}

TEST(SharedSequence, EurocShakeHasPoseTruth) {
  std::string why;
  const std::string path = test::sharedSequence("euroc_mh01_shake", &why);
  if (path.empty()) GTEST_SKIP() << why;
  const Sequence seq = loadSequence(path);
  EXPECT_EQ(seq.truth, "poses");
  ASSERT_EQ(seq.image_paths.size(), 100u);
  EXPECT_FALSE(seq.hasGyro());
  // The data README: 1.20 deg of rotation per frame on average, up to 2.4 deg.
  double sum = 0, max = 0;
  for (size_t k = 1; k < seq.image_paths.size(); ++k) {
    Eigen::Matrix3d R;
    ASSERT_TRUE(seq.trueRotation(k, &R)) << "frame " << k;
    const double angle = Eigen::AngleAxisd(R).angle() / kDeg;
    sum += angle;
    max = std::max(max, angle);
  }
  EXPECT_NEAR(sum / 99.0, 1.20, 0.02);
  EXPECT_GT(max, 2.0);
  EXPECT_LT(max, 3.0);
}

TEST(Sequence, KittiLayoutReadsJpegAndOtherImageFiles) {
  // A phone's frames are JPEGs; any image file OpenCV reads is a frame, in name order, and other
  // files beside them are not.
  const fs::path root = fs::path(test::makeTempDir("seq_kitti_jpeg")) / "phone";
  writeImage(root / "image_0" / "000000.jpg");
  writeImage(root / "image_0" / "000001.JPEG");
  writeImage(root / "image_0" / "000002.png");
  writeFile(root / "image_0" / "notes.txt", "not a frame\n");
  writeFile(root / "calib.txt", "10 0 7.5 0 0 11 5.5 0 0 0 1 0\n");
  const Sequence seq = loadSequence(root.string());
  ASSERT_EQ(seq.image_paths.size(), 3u);
  EXPECT_EQ(fs::path(seq.image_paths[1]).filename(), "000001.JPEG");
  EXPECT_EQ(seq.camera.width(), 16);
  fs::remove_all(root / "image_0");
  writeFile(root / "image_0" / "notes.txt", "not a frame\n");
  expectLoadError(root.string(), "no images");
}

TEST(Sequence, KittiLayoutDetails) {
  const fs::path root = fs::path(test::makeTempDir("seq_kitti")) / "tiny";
  for (int k = 0; k < 3; ++k) writeImage(root / "image_0" / ("00000" + std::to_string(k) + ".png"));
  writeFile(root / "calib.txt", "10 0 7.5 0 0 11 5.5 0 0 0 1 0\n");  // bare numbers, image_0/
  Sequence seq = loadSequence(root.string() + "/");
  EXPECT_EQ(seq.name, "tiny");
  ASSERT_EQ(seq.image_paths.size(), 3u);
  EXPECT_FALSE(seq.hasPoses());
  EXPECT_NEAR(seq.stamps[2], 0.2, 1e-12);
  EXPECT_DOUBLE_EQ(seq.camera.fy(), 11.0);
  Eigen::Matrix3d R;
  Eigen::Vector3d w;
  EXPECT_FALSE(seq.trueRotation(1, &R));
  EXPECT_FALSE(seq.trueAngularVelocity(1, &w));

  writeFile(root / "times.txt", "0.0\n0.05\n0.125\n");
  const Eigen::Matrix3d Ry = Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY()).toRotationMatrix();
  std::string poses;
  for (int k = 0; k < 3; ++k) {
    Eigen::Matrix3d Rk = Eigen::Matrix3d::Identity();
    for (int i = 0; i < k; ++i) Rk = Rk * Ry;
    char line[512];
    std::snprintf(line, sizeof(line), "%.12e %.12e %.12e %d %.12e %.12e %.12e 0 %.12e %.12e %.12e %d\n", Rk(0, 0),
                  Rk(0, 1), Rk(0, 2), k, Rk(1, 0), Rk(1, 1), Rk(1, 2), Rk(2, 0), Rk(2, 1), Rk(2, 2), 2 * k);
    poses += line;
  }
  writeFile(root / "poses.txt", poses);
  seq = loadSequence(root.string());
  EXPECT_NEAR(seq.stamps[2], 0.125, 1e-12);
  ASSERT_TRUE(seq.trueRotation(2, &R));
  EXPECT_NEAR(yawOf(R), 0.02, 1e-10);
  ASSERT_TRUE(seq.trueAngularVelocity(2, &w));
  EXPECT_LT((w - Eigen::Vector3d(0, 0.02 / 0.075, 0)).norm(), 1e-8);
  EXPECT_LT((seq.positions[2] - Eigen::Vector3d(2, 0, 4)).norm(), 1e-12);
  // The poses' own error: KITTI's by default (heading about camera y), what truth_sigma_deg.txt
  // says when present (one number for every axis, or three).
  EXPECT_EQ(seq.truth_sigma_deg, Eigen::Vector3d(kKittiPosesTiltSigmaDeg, kKittiPosesHeadingSigmaDeg, kKittiPosesTiltSigmaDeg));
  writeFile(root / kTruthSigmaFile, "0.0125\n");
  EXPECT_EQ(loadSequence(root.string()).truth_sigma_deg, Eigen::Vector3d::Constant(0.0125));
  writeFile(root / kTruthSigmaFile, "0.01 0.02\n0.03\n");
  EXPECT_EQ(loadSequence(root.string()).truth_sigma_deg, Eigen::Vector3d(0.01, 0.02, 0.03));
  fs::remove_all(root.parent_path());
}

/// Intensity-weighted centroid [px] of a grey image (pixel centres at whole coordinates).
Eigen::Vector2d centroid(const cv::Mat& image) {
  cv::Mat grey;
  image.convertTo(grey, CV_64F);
  double mass = 0.0, x = 0.0, y = 0.0;
  for (int r = 0; r < grey.rows; ++r)
    for (int c = 0; c < grey.cols; ++c) {
      const double v = grey.at<double>(r, c);
      mass += v;
      x += v * c;
      y += v * r;
    }
  return Eigen::Vector2d(x / mass, y / mass);
}

// Downscaling as evaluate --scale does it: a blob's centre, seen through the downscaled image,
// lies where the downscaled camera model projects the blob's bearing, at every factor (integer
// ratios and not); the distortion stays as it was.
TEST(Sequence, DownscaledCameraProjectsWhereTheDownscaledImageShows) {
  const CameraModel camera(400.0, 380.0, 199.3, 151.7, 401, 301, DistortionModel::kPlumbBob,
                           {-0.12, 0.03, 0.001, -0.0005});
  const Eigen::Vector2d blob(231.3, 118.8);
  cv::Mat image(camera.height(), camera.width(), CV_8UC1);
  for (int r = 0; r < image.rows; ++r)
    for (int c = 0; c < image.cols; ++c) {
      const double d2 = (c - blob.x()) * (c - blob.x()) + (r - blob.y()) * (r - blob.y());
      image.at<uint8_t>(r, c) = static_cast<uint8_t>(std::lround(250.0 * std::exp(-d2 / (2.0 * 7.0 * 7.0))));
    }
  ASSERT_LT((centroid(image) - blob).norm(), 0.01);
  const Eigen::Vector3d bearing = camera.bearing(blob.x(), blob.y());
  for (double factor : {0.5, 0.25, 0.2, 0.15, 0.1}) {
    SCOPED_TRACE(factor);
    const cv::Mat small = scaledImage(image, factor);
    const CameraModel scaled = scaledCamera(camera, factor);
    ASSERT_EQ(small.cols, scaled.width());
    ASSERT_EQ(small.rows, scaled.height());
    EXPECT_EQ(small.cols, std::lround(401 * factor));
    EXPECT_EQ(small.rows, std::lround(301 * factor));
    EXPECT_EQ(scaled.distortion(), camera.distortion());
    EXPECT_EQ(scaled.distortionModel(), camera.distortionModel());
    EXPECT_TRUE(scaled.validate().empty()) << scaled.validate();
    // Area interpolation keeps each pixel's mass where its area went: the centroid follows the
    // pixels' mapping, which the model must follow too.
    const Eigen::Vector2d seen = centroid(small), projected = scaled.project(bearing);
    std::printf("factor %.2f: blob at (%.3f, %.3f) px, projected at (%.3f, %.3f) px\n", factor, seen.x(), seen.y(),
                projected.x(), projected.y());
    EXPECT_LT((seen - projected).norm(), 0.03);
  }
  // Factor 1 changes nothing; a tiny image keeps at least one pixel a side.
  EXPECT_EQ(scaledCamera(camera, 1.0).fx(), camera.fx());
  EXPECT_EQ(scaledCamera(camera, 1.0).cx(), camera.cx());
  EXPECT_EQ(cv::norm(scaledImage(image, 1.0), image, cv::NORM_INF), 0.0);
  EXPECT_EQ(scaledImageSize(5, 3, 0.1), cv::Size(1, 1));
  for (double bad : {0.0, -0.5, 1.01, std::nan("")}) {
    EXPECT_THROW(scaledImageSize(401, 301, bad), std::invalid_argument) << bad;
    EXPECT_THROW(scaledCamera(camera, bad), std::invalid_argument) << bad;
  }
  EXPECT_THROW(scaledImage(cv::Mat(), 0.5), std::invalid_argument);
  EXPECT_THROW(scaledImageSize(0, 10, 0.5), std::invalid_argument);
}

// A loaded sequence downscaled once: its camera and every image it reads shrink alike.
TEST(Sequence, ScaledSequenceReadsDownscaledImages) {
  const fs::path root = fs::path(test::makeTempDir("seq_scaled")) / "tiny";
  for (int k = 0; k < 2; ++k) writeImage(root / "image_0" / ("00000" + std::to_string(k) + ".png"));
  writeFile(root / "calib.txt", "10 0 7.5 0 0 11 5.5 0 0 0 1 0\n");
  Sequence seq = loadSequence(root.string());
  EXPECT_EQ(readImage(seq, 1).size(), cv::Size(16, 12));
  scaleSequence(&seq, 0.5);
  EXPECT_EQ(seq.image_scale, 0.5);
  EXPECT_EQ(readImage(seq, 1).size(), cv::Size(8, 6));
  EXPECT_EQ(seq.camera.width(), 8);
  EXPECT_DOUBLE_EQ(seq.camera.fx(), 5.0);
  EXPECT_DOUBLE_EQ(seq.camera.cx(), (7.5 + 0.5) * 0.5 - 0.5);
  EXPECT_THROW(scaleSequence(&seq, 0.5), std::invalid_argument);
  EXPECT_THROW(readImage(seq, 2), std::runtime_error);
  fs::remove_all(root.parent_path());
}

TEST(Sequence, MalformedInputsNameTheFile) {
  const fs::path base(test::makeTempDir("seq_bad"));
  expectLoadError((base / "does_not_exist").string(), "does_not_exist");
  expectLoadError("", "no such folder");

  // Neither layout.
  fs::create_directories(base / "empty");
  expectLoadError((base / "empty").string(), "neither");

  // KITTI without calib.txt, then with garbage in it, then with a short matrix.
  const fs::path kitti = base / "kitti";
  writeImage(kitti / "image_l" / "000000.png");
  writeImage(kitti / "image_l" / "000001.png");
  expectLoadError(kitti.string(), "calib.txt");
  writeFile(kitti / "calib.txt", "P0: seven hundred and something\n");
  expectLoadError(kitti.string(), "calib.txt:1");
  writeFile(kitti / "calib.txt", "P0: 700 0 300 0 0 700 200 0 0 0 1\n");
  expectLoadError(kitti.string(), "calib.txt:1");
  writeFile(kitti / "calib.txt", "P0: 700 0 300 0 0 700 200 0 0 0 1 0\n");
  EXPECT_NO_THROW(loadSequence(kitti.string()));
  writeFile(kitti / "poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1\n");
  expectLoadError(kitti.string(), "poses.txt:2");
  writeFile(kitti / "poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n");
  expectLoadError(kitti.string(), "poses.txt");  // one pose for two images
  writeFile(kitti / "poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 0 0 1 0 0 0 0 1 0\n");
  expectLoadError(kitti.string(), "poses.txt:2");  // not a rotation
  fs::remove(kitti / "poses.txt");
  writeFile(kitti / "times.txt", "0.0\nsoon\n");
  expectLoadError(kitti.string(), "times.txt:2");
  writeFile(kitti / "times.txt", "0.1\n0.0\n");
  expectLoadError(kitti.string(), "times.txt:2");
  fs::remove(kitti / "times.txt");
  writeFile(kitti / "poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 0\n");
  for (const char* bad : {"-0.01\n", "0.01 0.02\n", "0.01 0.02 0.03 0.04\n", "0.01 -0.02 0.03\n",
                          "about a hundredth\n", "nan\n", "\n"}) {
    writeFile(kitti / kTruthSigmaFile, bad);
    expectLoadError(kitti.string(), kTruthSigmaFile);
  }
  fs::remove(kitti / kTruthSigmaFile);
  fs::remove(kitti / "poses.txt");
  // An unreadable "PNG".
  writeFile(kitti / "image_l" / "000000.png", "not a png");
  expectLoadError(kitti.string(), "000000.png");

  // EuRoC: missing data.csv, broken data.csv line, missing sensor.yaml, broken yaml.
  const fs::path euroc = base / "euroc";
  fs::create_directories(euroc / "cam0" / "data");
  expectLoadError(euroc.string(), "data.csv");
  writeFile(euroc / "cam0" / "data.csv", "#timestamp [ns],filename\n1000,1000.png\nnot-a-stamp,x.png\n");
  expectLoadError(euroc.string(), "data.csv:3");
  writeFile(euroc / "cam0" / "data.csv", "#timestamp [ns],filename\n1000,1000.png\n2000,2000.png\n");
  expectLoadError(euroc.string(), "sensor.yaml");
  writeFile(euroc / "cam0" / "sensor.yaml", "intrinsics: [1, 2, 3]\nresolution: [16, 12]\n");
  expectLoadError(euroc.string(), "sensor.yaml:1");
  writeFile(euroc / "cam0" / "sensor.yaml",
            "intrinsics: [10, 10, 8, 6]\nresolution: [16, 12]\ndistortion_model: none\n");
  expectLoadError(euroc.string(), "T_BS");
  writeFile(euroc / "cam0" / "sensor.yaml",
            "intrinsics: [10, 10, 8, 6]\nresolution: [16, 12]\ndistortion_model: none\n"
            "T_BS:\n  data: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0]\n");
  expectLoadError(euroc.string(), "sensor.yaml:4");
  writeFile(euroc / "cam0" / "sensor.yaml",
            "intrinsics: [10, 10, 8, 6]\nresolution: [16, 12]\ndistortion_model: mystery\n"
            "T_BS:\n  data: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]\n");
  expectLoadError(euroc.string(), "mystery");
  writeFile(euroc / "cam0" / "sensor.yaml",
            "intrinsics: [10, 10, 8, 6]\nresolution: [16, 12]\ndistortion_model: none\n"
            "T_BS:\n  data: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]\n");
  const Sequence ok = loadSequence(euroc.string());
  EXPECT_EQ(ok.image_paths.size(), 2u);
  EXPECT_FALSE(ok.hasGyro());
  writeFile(euroc / "imu0" / "data.csv", "#t,wx,wy,wz\n1000,0,0,0\n2000,0,zero,0\n");
  expectLoadError(euroc.string(), "imu0/data.csv:3");
  fs::remove_all(base);
}

}  // namespace
}  // namespace visual_gyro
