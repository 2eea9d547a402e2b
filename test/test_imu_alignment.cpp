// The camera-IMU alignment (include/visual_gyro/imu_alignment.h) and its command, calibrate_imu:
// a rendered hand-held sequence with a synthetic IMU of known offset, rotation, bias and noise; a
// rendered still camera; EuRoC's standing drone with its real IMU; and bad IMU input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "imu_alignment_report.h"
#include "json_writer.h"
#include "test_support.h"
#include "visual_gyro/geometry.h"
#include "visual_gyro/imu_alignment.h"
#include "visual_gyro/renderer.h"
#include "visual_gyro/sequence.h"
#include "visual_gyro/visual_gyro.h"

namespace vg = visual_gyro;

namespace {

namespace fs = std::filesystem;

// The synthetic IMU: 400 Hz, 13 ms late (t_imu = t_camera + 13 ms), rotated 90 deg about x then
// 10 deg about z from the camera, 0.02 rad/s of bias per axis and white noise.
constexpr double kImuRateHz = 400.0;
constexpr double kOffset = 0.013;
constexpr double kBias = 0.02;
constexpr double kImuNoise = 0.004;  // [rad/s] per sample

Eigen::Matrix3d imuFromCamera() {
  return (Eigen::AngleAxisd(10.0 * vg::kDegToRad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(90.0 * vg::kDegToRad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

/// A rendered sequence: its images, stamps, camera and the camera's true motion.
struct Rendered {
  vg::RenderSettings settings;
  std::vector<cv::Mat> images;
  std::vector<double> stamps;  ///< [s]
  /// The camera's orientation (camera -> world) at any of the given times [s].
  std::function<std::vector<Eigen::Matrix3d>(const std::vector<double>&)> orientations;
};

/// The hand-shaken camera near structure (drone_near: rotation about all three axes at rates up to
/// ~45 deg/s changing at 0.9-1.5 Hz, and parallax), 20 Hz.
Rendered shaken(int frames) {
  Rendered r;
  r.settings = vg::test::handheldRoom(480, 360, 380.0);
  r.settings.preset = vg::RenderPreset::kDroneNear;
  r.settings.frames = frames;
  r.settings.rate_hz = 20.0;
  const vg::RenderedSequence seq = vg::renderSequence(r.settings);
  r.images = seq.images;
  r.stamps = seq.stamps;
  const vg::RenderSettings settings = r.settings;
  r.orientations = [settings](const std::vector<double>& times) {
    std::vector<Eigen::Matrix3d> out(times.size());
    Eigen::Vector3d position;
    for (size_t k = 0; k < times.size(); ++k) vg::presetPose(settings, times[k], &out[k], &position);
    return out;
  };
  return r;
}

/// Views of the hand-held room at `orientation(t)` from a fixed point, 20 Hz, with fresh pixel
/// noise on every frame (renderView's own noise would repeat).
Rendered views(int frames, const std::function<Eigen::Matrix3d(double)>& orientation) {
  Rendered r;
  r.settings = vg::test::handheldRoom(480, 360, 380.0);
  r.settings.frames = frames;
  r.settings.rate_hz = 20.0;
  r.settings.noise_sigma = 0.0;
  vg::ImageDegradation noise;
  noise.noise_sigma = 2.0;
  for (int k = 0; k < frames; ++k) {
    const double t = k / r.settings.rate_hz;
    r.images.push_back(
        vg::degradeImage(vg::renderView(r.settings, orientation(t), Eigen::Vector3d::Zero()), noise, 1000 + k));
    r.stamps.push_back(t);
  }
  r.orientations = [orientation](const std::vector<double>& times) {
    std::vector<Eigen::Matrix3d> out;
    for (const double t : times) out.push_back(orientation(t));
    return out;
  };
  return r;
}

/// A camera standing still.
Rendered still(int frames) {
  return views(frames, [](double) { return Eigen::Matrix3d::Identity(); });
}

/// A camera turning to and fro about its y axis only: 6 deg amplitude at 1 Hz (up to 38 deg/s).
Rendered panning(int frames) {
  return views(frames, [](double t) {
    return Eigen::AngleAxisd(6.0 * vg::kDegToRad * std::sin(2.0 * vg::kPi * t), Eigen::Vector3d::UnitY())
        .toRotationMatrix();
  });
}

/// The pipeline's frame intervals over the images.
std::vector<vg::VisualRate> visualRates(const Rendered& r) {
  vg::VisualGyro gyro(vg::test::cameraOf(r.settings), vg::test::cpuSettings());
  std::vector<vg::VisualRate> rates;
  for (size_t k = 0; k < r.images.size(); ++k) {
    vg::VisualRate rate;
    if (vg::visualRateOf(gyro.processFrame(r.images[k], r.stamps[k]), r.stamps[k], &rate)) rates.push_back(rate);
  }
  return rates;
}

/// The synthetic IMU of a rendered sequence: the camera's angular velocity (camera frame, central
/// differences of its orientation) rotated into the IMU frame, scaled per IMU axis, plus bias and
/// noise, at 400 Hz from 0.5 s before the first image to 0.5 s after the last, stamped on the IMU's
/// clock (camera time + kOffset).
std::vector<vg::GyroSample> syntheticImu(const Rendered& r, uint64_t seed,
                                         const Eigen::Vector3d& scale = Eigen::Vector3d::Ones()) {
  const double begin = r.stamps.front() - 0.5, end = r.stamps.back() + 0.5, h = 1e-4;
  std::vector<double> times, imu_stamps;
  for (int i = 0; begin + i / kImuRateHz <= end; ++i) {
    const double t = begin + i / kImuRateHz;
    imu_stamps.push_back(t);
    times.push_back(t - kOffset - h);
    times.push_back(t - kOffset + h);
  }
  const std::vector<Eigen::Matrix3d> orientations = r.orientations(times);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, kImuNoise);
  std::vector<vg::GyroSample> imu;
  for (size_t i = 0; i < imu_stamps.size(); ++i) {
    const Eigen::Vector3d omega = vg::so3Log(orientations[2 * i].transpose() * orientations[2 * i + 1]) / (2.0 * h);
    vg::GyroSample s;
    s.stamp = imu_stamps[i];
    s.angular_velocity = scale.cwiseProduct(imuFromCamera() * omega) + Eigen::Vector3d::Constant(kBias) +
                         Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    imu.push_back(s);
  }
  return imu;
}

double rotationErrorDeg(const vg::ImuAlignment& a) {
  return vg::rotationAngleBetween(a.imu_from_camera.toRotationMatrix(), imuFromCamera()) * vg::kRadToDeg;
}

double biasError(const vg::ImuAlignment& a) {
  return (a.gyro_bias - Eigen::Vector3d::Constant(kBias)).cwiseAbs().maxCoeff();
}

void print(const char* what, const vg::ImuAlignment& a) {
  std::printf("%s: offset %.3f ms (sigma %.3f ms, observable %d), rotation %s, error %.3f deg (sigma %.3f deg), "
              "bias error %.5f rad/s (sigma %.5f), rate RMSE %.3f deg/s, explained %.3f, %d of %d frames used\n",
              what, a.time_offset * 1e3, a.time_offset_sigma * 1e3, a.offset_observable,
              vg::rotationObservabilityName(a.rotation), rotationErrorDeg(a), a.rotation_sigma_deg, biasError(a),
              a.gyro_bias_sigma.maxCoeff(), a.rate_rmse * vg::kRadToDeg, a.explained, a.frames_used, a.frames);
  for (const std::string& note : a.notes) std::printf("  note: %s\n", note.c_str());
}

/// The numbers of the JSON array under "key" in one JSON line; empty when absent or null.
std::vector<double> jsonArray(const std::string& line, const std::string& key) {
  std::vector<double> out;
  const std::string needle = "\"" + key + "\": [";
  const size_t at = line.find(needle);
  if (at == std::string::npos) return out;
  const char* p = line.c_str() + at + needle.size();
  while (*p != ']' && *p != '\0') {
    char* end = nullptr;
    out.push_back(std::strtod(p, &end));
    if (end == p) return {};
    p = end;
    while (*p == ',' || *p == ' ') ++p;
  }
  return out;
}

/// The last line of a command's output (calibrate_imu's JSON).
std::string lastLine(const std::string& output) {
  std::string text = output;
  while (!text.empty() && text.back() == '\n') text.pop_back();
  return text.substr(text.find_last_of('\n') + 1);
}

void writeText(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream out(path);
  out << text;
  ASSERT_TRUE(out.good()) << "cannot write " << path;
}

long long nanoseconds(double seconds) { return std::llround(seconds * 1e9); }

/// Writes images, stamps (shifted by `start` [s]) and IMU samples as a EuRoC-layout folder; T_BS is
/// the synthetic IMU's true rotation. The IMU is taken as given (any order, any rate).
void writeEuroc(const fs::path& root, const Rendered& r, const std::vector<vg::GyroSample>& imu, double start) {
  std::ostringstream csv;
  csv << "#timestamp [ns],filename\n";
  fs::create_directories(root / "cam0" / "data");
  for (size_t k = 0; k < r.images.size(); ++k) {
    const std::string name = std::to_string(nanoseconds(r.stamps[k] + start)) + ".png";
    ASSERT_TRUE(cv::imwrite((root / "cam0" / "data" / name).string(), r.images[k]));
    csv << nanoseconds(r.stamps[k] + start) << "," << name << "\n";
  }
  writeText(root / "cam0" / "data.csv", csv.str());
  const Eigen::Matrix3d t_bs = imuFromCamera();
  std::ostringstream yaml;
  yaml.precision(12);
  yaml << "sensor_type: camera\nresolution: [" << r.settings.width << ", " << r.settings.height << "]\n"
       << "intrinsics: [" << r.settings.fx << ", " << r.settings.fy << ", " << r.settings.cx << ", " << r.settings.cy
       << "]\ndistortion_model: none\nT_BS:\n  cols: 4\n  rows: 4\n  data: [";
  for (int row = 0; row < 4; ++row)
    for (int col = 0; col < 4; ++col) {
      const double v = row < 3 && col < 3 ? t_bs(row, col) : (row == col ? 1.0 : 0.0);
      yaml << v << (row == 3 && col == 3 ? "]\n" : ", ");
    }
  writeText(root / "cam0" / "sensor.yaml", yaml.str());
  if (imu.empty()) return;
  std::ostringstream imu_csv;
  imu_csv.precision(12);
  imu_csv << "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n";
  for (const vg::GyroSample& s : imu) {
    imu_csv << nanoseconds(s.stamp + start) << "," << s.angular_velocity.x() << "," << s.angular_velocity.y() << ","
            << s.angular_velocity.z() << ",0,0,9.81\n";
  }
  writeText(root / "imu0" / "data.csv", imu_csv.str());
}

/// A handful of plain frame intervals (30 Hz) for the input checks, which need no images.
std::vector<vg::VisualRate> someRates(double start, int count) {
  std::vector<vg::VisualRate> rates;
  for (int k = 1; k <= count; ++k) {
    vg::VisualRate r;
    r.start = start + (k - 1) / 30.0;
    r.end = start + k / 30.0;
    r.valid = true;
    r.rate = Eigen::Vector3d(std::sin(k), std::cos(k), 0.3);
    r.covariance = 1e-4 * Eigen::Matrix3d::Identity();
    rates.push_back(r);
  }
  return rates;
}

std::vector<vg::GyroSample> imuSamples(double start, double end, double rate_hz) {
  std::vector<vg::GyroSample> imu;
  for (int i = 0; start + i / rate_hz <= end; ++i) {
    vg::GyroSample s;
    s.stamp = start + i / rate_hz;
    imu.push_back(s);
  }
  return imu;
}

/// The message of the ImuAlignmentError alignImu throws, or "" when it does not throw one.
std::string alignmentError(const std::vector<vg::VisualRate>& rates, const std::vector<vg::GyroSample>& imu) {
  try {
    vg::alignImu(rates, imu, vg::ImuAlignmentSettings());
  } catch (const vg::ImuAlignmentError& e) {
    return e.what();
  }
  return "";
}

/// The hand-shaken sequence, its visual rates and its synthetic IMU, made once for the tests below.
class Shaken : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sequence_ = new Rendered(shaken(61));
    rates_ = new std::vector<vg::VisualRate>(visualRates(*sequence_));
    imu_ = new std::vector<vg::GyroSample>(syntheticImu(*sequence_, 5));
  }
  static void TearDownTestSuite() {
    delete sequence_;
    delete rates_;
    delete imu_;
  }
  static Rendered* sequence_;
  static std::vector<vg::VisualRate>* rates_;
  static std::vector<vg::GyroSample>* imu_;
};
Rendered* Shaken::sequence_ = nullptr;
std::vector<vg::VisualRate>* Shaken::rates_ = nullptr;
std::vector<vg::GyroSample>* Shaken::imu_ = nullptr;

}  // namespace

// A camera shaken by hand about all three axes for 3 s (20 Hz), with a 400 Hz IMU 13 ms late,
// rotated 90 deg about x then 10 deg about z, 0.02 rad/s of bias per axis and white noise: the
// offset within 1 ms, the rotation within 0.3 deg and the bias within 0.002 rad/s.
TEST_F(Shaken, RecoversOffsetRotationAndBias) {
  const vg::ImuAlignment a = vg::alignImu(*rates_, *imu_, vg::ImuAlignmentSettings());
  print("shaken", a);
  EXPECT_TRUE(a.motion);
  ASSERT_TRUE(a.offset_observable);
  ASSERT_EQ(a.rotation, vg::RotationObservability::kFull);
  EXPECT_NEAR(a.time_offset, kOffset, 0.001);
  EXPECT_LT(rotationErrorDeg(a), 0.3);
  EXPECT_LT(biasError(a), 0.002);
  EXPECT_TRUE(a.notes.empty());
  EXPECT_EQ(a.frames_used, a.frames_valid);
  EXPECT_GT(a.frames_valid, 55);
  // The uncertainties are of the size of the errors, not orders of magnitude off.
  EXPECT_LT(a.time_offset_sigma, 0.001);
  EXPECT_GT(a.time_offset_sigma, 1e-6);
  EXPECT_LT(a.rotation_sigma_deg, 0.3);
  EXPECT_LT(a.gyro_bias_sigma.maxCoeff(), 0.002);
  EXPECT_NEAR(a.imu_rate_hz, kImuRateHz, 1.0);
  EXPECT_NEAR(a.gyro_noise, kImuNoise, 0.3 * kImuNoise) << "from the IMU's second differences";
}

// The same IMU reading 2 % high about x and 1 % low about y: with --scale the scale is found; the
// other estimates stay as good.
TEST_F(Shaken, RecoversTheGyroScaleWhenAsked) {
  const Eigen::Vector3d scale(1.02, 0.99, 1.0);
  vg::ImuAlignmentSettings settings;
  settings.estimate_scale = true;
  const vg::ImuAlignment a = vg::alignImu(*rates_, syntheticImu(*sequence_, 5, scale), settings);
  print("shaken, scaled IMU", a);
  std::printf("  scale %.4f %.4f %.4f (sigma %.4f %.4f %.4f)\n", a.gyro_scale.x(), a.gyro_scale.y(), a.gyro_scale.z(),
              a.gyro_scale_sigma.x(), a.gyro_scale_sigma.y(), a.gyro_scale_sigma.z());
  ASSERT_TRUE(a.has_scale);
  EXPECT_LT((a.gyro_scale - scale).cwiseAbs().maxCoeff(), 0.005);
  EXPECT_NEAR(a.time_offset, kOffset, 0.001);
  EXPECT_LT(rotationErrorDeg(a), 0.3);
  EXPECT_LT(biasError(a), 0.002);
  // Without --scale the scale error ends up elsewhere: the rates fit worse.
  const vg::ImuAlignment plain = vg::alignImu(*rates_, syntheticImu(*sequence_, 5, scale), vg::ImuAlignmentSettings());
  EXPECT_GT(plain.rate_rmse, a.rate_rmse);
}

// The aligned gyro undoes what the alignment found: on the camera's clock, without its bias.
TEST_F(Shaken, AlignedGyroIsOnTheCameraClockWithoutBias) {
  const vg::ImuAlignment a = vg::alignImu(*rates_, *imu_, vg::ImuAlignmentSettings());
  const std::vector<vg::GyroSample> aligned = vg::alignedGyro(*imu_, a);
  ASSERT_EQ(aligned.size(), imu_->size());
  for (size_t i = 0; i < imu_->size(); i += 97) {
    EXPECT_NEAR(aligned[i].stamp, (*imu_)[i].stamp - a.time_offset, 1e-12);
    EXPECT_LT((aligned[i].angular_velocity - ((*imu_)[i].angular_velocity - a.gyro_bias)).norm(), 1e-12);
  }
}

// The end-to-end command on the same data written as a EuRoC folder, and as a bag made from that
// folder by make_bag: both find what the core finds (the bag's IMU ends at the last image, so it
// covers a few frames fewer).
TEST_F(Shaken, CommandFindsTheSameFromAFolderAndFromABag) {
  const fs::path root = vg::test::makeTempDir("calibrate_imu");
  writeEuroc(root / "shaken", *sequence_, *imu_, 1.0);
  int status = -1;
  const std::string folder_out =
      vg::test::runCommand(std::string(VISUAL_GYRO_CALIBRATE_IMU) + " " + (root / "shaken").string() +
                               " --backend cpu --quiet",
                           &status);
  ASSERT_EQ(status, 0) << folder_out;
  std::printf("%s", folder_out.c_str());
  const std::string bag = (root / "shaken.bag").string();
  const std::string made =
      vg::test::runCommand(std::string(VISUAL_GYRO_MAKE_BAG) + " " + (root / "shaken").string() + " " + bag, &status);
  ASSERT_EQ(status, 0) << made;
  const std::string bag_out = vg::test::runCommand(
      std::string(VISUAL_GYRO_CALIBRATE_IMU) + " " + bag +
          " --image-topic /camera/image_raw --imu-topic /imu/data --backend cpu --quiet",
      &status);
  ASSERT_EQ(status, 0) << bag_out;
  for (const std::string& out : {folder_out, bag_out}) {
    const std::string json = lastLine(out);
    SCOPED_TRACE(json);
    EXPECT_NEAR(vg::test::jsonNumber(json, "time_offset_ms"), kOffset * 1e3, 1.0);
    EXPECT_EQ(vg::test::jsonString(json, "rotation_observable"), "full");
    const std::vector<double> q = jsonArray(json, "rotation_imu_from_camera");
    ASSERT_EQ(q.size(), 4u);
    const Eigen::Quaterniond found(q[3], q[0], q[1], q[2]);
    EXPECT_LT(vg::rotationAngleBetween(found.toRotationMatrix(), imuFromCamera()) * vg::kRadToDeg, 0.3);
    EXPECT_LT(vg::test::jsonNumber(json, "reference_rotation_error_deg"), 0.3) << "against T_BS (the bag's /tf_static)";
    const std::vector<double> bias = jsonArray(json, "gyro_bias_rad_s");
    ASSERT_EQ(bias.size(), 3u);
    for (const double b : bias) EXPECT_NEAR(b, kBias, 0.002);
    EXPECT_NE(json.find("\"gyro_scale\": null"), std::string::npos) << "without --scale";
  }
  // The snippets to paste: the node's parameter and the static tf with the quaternion.
  EXPECT_NE(folder_out.find("time_offset: 0.01"), std::string::npos);
  EXPECT_NE(folder_out.find("static_transform_publisher"), std::string::npos);
  EXPECT_NE(folder_out.find(" imu camera_optical\""), std::string::npos);
  EXPECT_NE(bag_out.find("gyro_bias: ["), std::string::npos);
  EXPECT_NEAR(vg::test::jsonNumber(lastLine(bag_out), "time_offset_ms"),
              vg::test::jsonNumber(lastLine(folder_out), "time_offset_ms"), 0.2);
  fs::remove_all(root);
}

// A camera standing still: the IMU's bias comes out; offset and rotation are not observable and
// say so (null in the JSON).
TEST(ImuAlignment, StillCameraGivesTheBiasAndNoOffsetOrRotation) {
  const Rendered r = still(31);
  const vg::ImuAlignment a = vg::alignImu(visualRates(r), syntheticImu(r, 9), vg::ImuAlignmentSettings());
  print("still", a);
  EXPECT_FALSE(a.motion);
  EXPECT_LT(a.explained, 0.5);
  EXPECT_FALSE(a.offset_observable);
  EXPECT_EQ(a.time_offset, 0.0);
  EXPECT_EQ(a.rotation, vg::RotationObservability::kNone);
  EXPECT_LT(biasError(a), 0.002);
  ASSERT_GE(a.notes.size(), 2u);
  EXPECT_NE(a.notes[0].find("time offset not observable"), std::string::npos);
  EXPECT_NE(a.notes[1].find("rotation not observable"), std::string::npos);
  vg::JsonObject json;
  vg::eval::addAlignmentFields(a, vg::eval::AlignmentSource(), &json);
  EXPECT_NE(json.str().find("\"time_offset_ms\": null"), std::string::npos) << json.str();
  EXPECT_NE(json.str().find("\"rotation_imu_from_camera\": null"), std::string::npos) << json.str();
  EXPECT_EQ(jsonArray(json.str(), "gyro_bias_rad_s").size(), 3u) << json.str();
}

// A camera panning about its y axis only: the offset and the bias are observable, and so is where
// that axis lies in the IMU frame, but not the angle about it.
TEST(ImuAlignment, RotationAboutOneAxisGivesTheAxisOnly) {
  const Rendered r = panning(31);
  const vg::ImuAlignment a = vg::alignImu(visualRates(r), syntheticImu(r, 11), vg::ImuAlignmentSettings());
  print("panning", a);
  EXPECT_TRUE(a.motion);
  ASSERT_TRUE(a.offset_observable);
  EXPECT_NEAR(a.time_offset, kOffset, 0.001);
  ASSERT_EQ(a.rotation, vg::RotationObservability::kAxisOnly);
  EXPECT_GT(std::abs(a.rotation_axis_camera.y()), std::cos(2.0 * vg::kDegToRad)) << a.rotation_axis_camera;
  EXPECT_LT((a.rotation_axis_imu - imuFromCamera() * a.rotation_axis_camera).norm(), 2.0 * vg::kDegToRad);
  EXPECT_LT(biasError(a), 0.002);
  vg::JsonObject json;
  vg::eval::addAlignmentFields(a, vg::eval::AlignmentSource(), &json);
  EXPECT_NE(json.str().find("\"rotation_imu_from_camera\": null"), std::string::npos) << json.str();
  EXPECT_EQ(jsonArray(json.str(), "rotation_axis_imu").size(), 3u) << json.str();
}

// EuRoC's drone standing on the ground with its real IMU (ADIS16448, 200 Hz): the bias matches
// EuRoC's own (about -0.002, 0.021, 0.078 rad/s). The camera is not quite still (a vibration of
// about 0.5 deg/s that camera and IMU both see), so whatever else is observable must agree with
// the hardware-synchronised sensor and its T_BS: an offset near zero and the vibration's axis.
TEST(ImuAlignment, EurocStandingDroneBiasMatchesEurocsOwn) {
  std::string why;
  const std::string folder = vg::test::sharedSequence("euroc_v101_static", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  int status = -1;
  const std::string out =
      vg::test::runCommand(std::string(VISUAL_GYRO_CALIBRATE_IMU) + " " + folder + " --backend cpu --quiet", &status);
  ASSERT_EQ(status, 0) << out;
  std::printf("%s", out.c_str());
  const std::string json = lastLine(out);
  const std::vector<double> bias = jsonArray(json, "gyro_bias_rad_s");
  ASSERT_EQ(bias.size(), 3u) << json;
  const double euroc[3] = {-0.002, 0.021, 0.078};
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(bias[i], euroc[i], 0.002) << "axis " << i;
  const double offset_ms = vg::test::jsonNumber(json, "time_offset_ms");
  if (std::isfinite(offset_ms)) EXPECT_LT(std::abs(offset_ms), 1.0);
  const vg::Sequence seq = vg::loadSequence(folder);
  const std::vector<double> axis_camera = jsonArray(json, "rotation_axis_camera");
  const std::vector<double> axis_imu = jsonArray(json, "rotation_axis_imu");
  if (axis_camera.size() == 3 && axis_imu.size() == 3) {
    const Eigen::Vector3d mapped =
        seq.body_from_camera * Eigen::Vector3d(axis_camera[0], axis_camera[1], axis_camera[2]);
    EXPECT_LT((mapped - Eigen::Vector3d(axis_imu[0], axis_imu[1], axis_imu[2])).norm(), 3.0 * vg::kDegToRad);
  }
  const double rotation_error = vg::test::jsonNumber(json, "reference_rotation_error_deg");
  if (std::isfinite(rotation_error)) EXPECT_LT(rotation_error, 3.0);
}

// Bad IMU input to the core: a clear error each, naming the problem.
TEST(ImuAlignment, BadImuInputIsAClearError) {
  const std::vector<vg::VisualRate> rates = someRates(100.0, 40);
  EXPECT_NE(alignmentError(rates, {}).find("no IMU samples"), std::string::npos);
  EXPECT_NE(alignmentError(rates, imuSamples(200.0, 202.0, 200.0)).find("do not overlap"), std::string::npos);
  std::vector<vg::GyroSample> backwards = imuSamples(99.0, 103.0, 200.0);
  std::swap(backwards[300], backwards[301]);
  EXPECT_NE(alignmentError(rates, backwards).find("IMU stamps must increase: sample 301"), std::string::npos)
      << alignmentError(rates, backwards);
  const std::string slow = alignmentError(rates, imuSamples(99.0, 103.0, 10.0));
  EXPECT_NE(slow.find("the IMU samples at 10 Hz"), std::string::npos) << slow;
  std::vector<vg::GyroSample> nan_rate = imuSamples(99.0, 103.0, 200.0);
  nan_rate[5].angular_velocity.x() = std::nan("");
  EXPECT_NE(alignmentError(rates, nan_rate).find("not finite"), std::string::npos);
  // Too few valid frames inside the IMU's span.
  EXPECT_NE(alignmentError(someRates(100.0, 5), imuSamples(99.0, 103.0, 200.0)).find("at least 10"),
            std::string::npos);
  // Good input passes the same checks.
  EXPECT_EQ(alignmentError(rates, imuSamples(99.0, 103.0, 200.0)), "");
}

// The command's exit status: 1 with the reason for bad data, 2 for a bad command line.
TEST(ImuAlignment, CommandExitsWithStatusOneForBadImuInput) {
  const fs::path root = vg::test::makeTempDir("calibrate_imu_bad");
  const Rendered r = still(3);
  const double first = 1.0;  // the images' first stamp [s]; the IMU's are shifted alike
  struct Case {
    const char* name;
    std::vector<vg::GyroSample> imu;
    const char* says;
  };
  std::vector<vg::GyroSample> backwards = imuSamples(-1.0, 2.0, 200.0);
  std::swap(backwards[100], backwards[101]);
  const std::vector<Case> cases = {
      {"no_imu", {}, "no IMU"},
      {"not_overlapping", imuSamples(5.0, 6.0, 200.0), "do not overlap"},
      {"backwards", backwards, "time stamps must increase"},
      {"ten_hz", imuSamples(-1.0, 2.0, 10.0), "samples per frame interval"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    writeEuroc(root / c.name, r, c.imu, first);
    int status = -1;
    const std::string out = vg::test::runCommand(
        std::string(VISUAL_GYRO_CALIBRATE_IMU) + " " + (root / c.name).string() + " --quiet", &status);
    EXPECT_EQ(status, 1) << out;
    EXPECT_NE(out.find(c.says), std::string::npos) << out;
  }
  int status = -1;
  const std::string bad_option = vg::test::runCommand(
      std::string(VISUAL_GYRO_CALIBRATE_IMU) + " " + (root / "no_imu").string() + " --max-offset -5", &status);
  EXPECT_EQ(status, 2) << bad_option;
  const std::string missing = vg::test::runCommand(std::string(VISUAL_GYRO_CALIBRATE_IMU) + " " +
                                                       (root / "nothing_here.bag").string() + " --quiet",
                                                   &status);
  EXPECT_EQ(status, 1) << missing;
  EXPECT_NE(missing.find("cannot read bag"), std::string::npos) << missing;
  fs::remove_all(root);
}

// evaluate scores a gyro reference after the same alignment (bias and offset removed, the data's
// T_BS kept): on euroc_v101_static the error is the estimate's own, no longer the IMU's bias
// (about 0.23 deg per pair as recorded, --raw-gyro).
TEST(ImuAlignment, EvaluateAlignsAGyroReference) {
  std::string why;
  const std::string folder = vg::test::sharedSequence("euroc_v101_static", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  int status = -1;
  const std::string base = std::string(VISUAL_GYRO_EVALUATE) + " " + folder + " --method vote --backend cpu --quiet";
  const std::string aligned = lastLine(vg::test::runCommand(base, &status));
  ASSERT_EQ(status, 0) << aligned;
  const std::string raw = lastLine(vg::test::runCommand(base + " --raw-gyro", &status));
  ASSERT_EQ(status, 0) << raw;
  std::printf("vote on euroc_v101_static: rotation RMSE %.4f deg against the aligned gyro, %.4f deg against the "
              "raw gyro\n",
              vg::test::jsonNumber(aligned, "rot_rmse_deg"), vg::test::jsonNumber(raw, "rot_rmse_deg"));
  EXPECT_NE(aligned.find("\"gyro_aligned\": true"), std::string::npos) << aligned;
  const std::vector<double> bias = jsonArray(aligned, "gyro_bias_rad_s");
  ASSERT_EQ(bias.size(), 3u) << aligned;
  const double euroc[3] = {-0.002, 0.021, 0.078};
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(bias[i], euroc[i], 0.002) << "axis " << i;
  EXPECT_LT(vg::test::jsonNumber(aligned, "rot_rmse_deg"), 0.05);
  EXPECT_GT(vg::test::jsonNumber(raw, "rot_rmse_deg"), 0.2);
  EXPECT_NE(raw.find("\"gyro_bias_rad_s\": null"), std::string::npos) << raw;
  EXPECT_NE(raw.find("\"time_offset_ms\": null"), std::string::npos) << raw;
}
