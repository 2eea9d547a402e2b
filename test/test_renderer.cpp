// Synthetic renderer: geometry (infinite homography between rotated views), KITTI round trip,
// texture richness, motion of the presets, bad input.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "test_support.h"
#include "visual_gyro/renderer.h"
#include "visual_gyro/sequence.h"

namespace visual_gyro {
namespace {

constexpr double kDeg = M_PI / 180.0;

Eigen::Matrix3d rotation(double angle_deg, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(angle_deg * kDeg, axis.normalized()).toRotationMatrix();
}

double rotationAngleDeg(const Eigen::Matrix3d& R) { return Eigen::AngleAxisd(R).angle() / kDeg; }

cv::Mat toCv(const Eigen::Matrix3d& m) {
  cv::Mat out(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out.at<double>(r, c) = m(r, c);
  return out;
}

/// Mean absolute difference between view 1 and view 2 warped into view 1 by the infinite
/// homography of `relative` (= R1^T R2: maps view-2 bearings into view 1).
double warpedDifference(const cv::Mat& view1, const cv::Mat& view2, const Eigen::Matrix3d& K,
                        const Eigen::Matrix3d& relative, double* overlap) {
  const Eigen::Matrix3d H = K * relative * K.inverse();  // view-2 pixel -> view-1 pixel
  cv::Mat warped, mask;
  cv::warpPerspective(view2, warped, toCv(H), view1.size(), cv::INTER_LINEAR);
  cv::warpPerspective(cv::Mat(view2.size(), CV_8U, cv::Scalar(255)), mask, toCv(H), view1.size(), cv::INTER_NEAREST);
  cv::erode(mask, mask, cv::Mat(), cv::Point(-1, -1), 3);
  cv::Mat diff;
  cv::absdiff(view1, warped, diff);
  *overlap = cv::countNonZero(mask) / static_cast<double>(mask.total());
  return cv::mean(diff, mask)[0];
}

TEST(Renderer, RotatedViewsAreRelatedByTheInfiniteHomography) {
  RenderSettings settings;
  settings.preset = RenderPreset::kHandheld;
  settings.noise_sigma = 0.0;
  Eigen::Matrix3d K;
  K << settings.fx, 0, settings.cx, 0, settings.fy, settings.cy, 0, 0, 1;
  const Eigen::Vector3d position(0.1, -0.05, 0.2);
  const Eigen::Matrix3d R1 = rotation(10.0, Eigen::Vector3d(0.2, 1.0, -0.1));
  const Eigen::Matrix3d relative = rotation(4.0, Eigen::Vector3d(0.3, 1.0, 0.4));
  const Eigen::Matrix3d R2 = R1 * relative;
  const cv::Mat view1 = renderView(settings, R1, position);
  const cv::Mat view2 = renderView(settings, R2, position);
  ASSERT_EQ(view1.type(), CV_8UC1);
  ASSERT_EQ(view1.size(), cv::Size(640, 480));

  double overlap = 0;
  const double right = warpedDifference(view1, view2, K, relative, &overlap);
  EXPECT_GT(overlap, 0.6);
  // A rotation 0.5 deg off, and the inverse rotation (the wrong convention).
  const double off = warpedDifference(view1, view2, K, relative * rotation(0.5, Eigen::Vector3d(1, 0, 0)), &overlap);
  const double inverse = warpedDifference(view1, view2, K, relative.transpose(), &overlap);
  const double unwarped = warpedDifference(view1, view2, K, Eigen::Matrix3d::Identity(), &overlap);
  std::printf("mean |view1 - warped view2|: true rotation %.2f, 0.5 deg off %.2f, inverse %.2f, none %.2f\n", right,
              off, inverse, unwarped);
  EXPECT_LT(right, 6.0);
  EXPECT_GT(off, 2.5 * right);
  EXPECT_GT(inverse, 4.0 * right);
  EXPECT_GT(unwarped, 4.0 * right);
}

TEST(Renderer, SameSeedSameImagesOtherSeedOtherTexture) {
  RenderSettings settings;
  settings.preset = RenderPreset::kHandheld;
  settings.setCentredCamera(160, 120, 125.0);
  const Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  const Eigen::Vector3d p = Eigen::Vector3d::Zero();
  const cv::Mat a = renderView(settings, R, p);
  const cv::Mat b = renderView(settings, R, p);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_L1), 0.0);
  settings.seed = 8;
  const cv::Mat c = renderView(settings, R, p);
  EXPECT_GT(cv::norm(a, c, cv::NORM_L1) / a.total(), 10.0);
}

TEST(Renderer, KittiLayoutLoadsBack) {
  RenderSettings settings;
  settings.preset = RenderPreset::kDrive;
  settings.frames = 6;
  settings.setCentredCamera(320, 240, 250.0);
  const RenderedSequence rendered = renderSequence(settings);
  ASSERT_EQ(rendered.images.size(), 6u);
  const std::string dir = test::makeTempDir("render_kitti") + "/synthetic_drive";
  writeKittiLayout(rendered, dir);

  const Sequence seq = loadSequence(dir);
  EXPECT_EQ(seq.name, "synthetic_drive");
  EXPECT_EQ(seq.layout, "kitti");
  ASSERT_EQ(seq.image_paths.size(), 6u);
  EXPECT_EQ(seq.camera.width(), 320);
  EXPECT_EQ(seq.camera.height(), 240);
  EXPECT_DOUBLE_EQ(seq.camera.fx(), 250.0);
  EXPECT_DOUBLE_EQ(seq.camera.fy(), 250.0);
  EXPECT_DOUBLE_EQ(seq.camera.cx(), 159.5);
  EXPECT_DOUBLE_EQ(seq.camera.cy(), 119.5);
  ASSERT_TRUE(seq.hasPoses());
  EXPECT_TRUE(seq.truth_sigma_deg.isZero());  // rendered from these poses: exact
  ASSERT_EQ(seq.stamps.size(), 6u);
  for (size_t k = 0; k < 6; ++k) {
    EXPECT_NEAR(seq.stamps[k], rendered.stamps[k], 1e-9);
    EXPECT_NEAR(seq.stamps[k], k * 0.1, 1e-9);
    EXPECT_LT((seq.positions[k] - rendered.positions[k]).norm(), 1e-6);
    if (k == 0) continue;
    Eigen::Matrix3d loaded;
    ASSERT_TRUE(seq.trueRotation(k, &loaded));
    const Eigen::Matrix3d truth = rendered.orientations[k - 1].transpose() * rendered.orientations[k];
    EXPECT_LT((loaded - truth).norm(), 1e-7) << "frame " << k;
    Eigen::Vector3d omega;
    ASSERT_TRUE(seq.trueAngularVelocity(k, &omega));
    EXPECT_NEAR(omega.norm() * 0.1 / kDeg, rotationAngleDeg(truth), 1e-5);
  }
  const cv::Mat image = cv::imread(seq.image_paths[3], cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(cv::norm(image, rendered.images[3], cv::NORM_INF), 0.0);
  std::filesystem::remove_all(std::filesystem::path(dir).parent_path());
}

TEST(Renderer, EveryPresetHasEnoughFastCorners) {
  for (const std::string preset : {"drive", "handheld", "forward"}) {
    RenderSettings settings;
    ASSERT_TRUE(parsePreset(preset, &settings.preset));
    settings.frames = 3;
    settings.rate_hz = presetRateHz(settings.preset);
    const auto start = std::chrono::steady_clock::now();
    const RenderedSequence seq = renderSequence(settings);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    // Per-frame time without the scene set-up: render the last pose again (scene cached).
    const auto view_start = std::chrono::steady_clock::now();
    renderView(settings, seq.orientations.back(), seq.positions.back());
    const double view_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - view_start).count();
    for (size_t k = 0; k < seq.images.size(); ++k) {
      std::vector<cv::KeyPoint> corners;
      cv::FAST(seq.images[k], corners, 20, true);
      if (k == 0)
        std::printf("%-8s frame 0: %zu FAST corners (threshold 20); 3 frames incl. scene set-up %.0f ms, one view %.0f ms\n",
                    preset.c_str(), corners.size(), ms, view_ms);
      EXPECT_GE(corners.size(), 300u) << preset << " frame " << k;
      // Not a blank or saturated image.
      cv::Scalar mean, stddev;
      cv::meanStdDev(seq.images[k], mean, stddev);
      EXPECT_GT(stddev[0], 20.0) << preset;
      EXPECT_GT(mean[0], 40.0) << preset;
      EXPECT_LT(mean[0], 215.0) << preset;
    }
  }
}

TEST(Renderer, PresetMotionMatchesItsDescription) {
  struct Expect {
    std::string preset;
    double rate_hz;
    int frames;
    double min_peak_deg, max_peak_deg;  // largest rotation per frame
    double min_step_m, max_step_m;      // translation per frame
  };
  const Expect cases[] = {{"drive", 10.0, 60, 2.5, 3.3, 0.99, 1.01},
                          {"forward", 10.0, 60, 0.0, 0.1, 0.99, 1.01},
                          {"handheld", 30.0, 90, 0.8, 1.5, 0.0, 0.005}};
  for (const auto& c : cases) {
    RenderSettings settings;
    ASSERT_TRUE(parsePreset(c.preset, &settings.preset));
    settings.frames = c.frames;
    settings.rate_hz = c.rate_hz;
    settings.setCentredCamera(32, 24, 25.0);  // motion only: tiny images
    const RenderedSequence seq = renderSequence(settings);
    ASSERT_EQ(seq.orientations.size(), static_cast<size_t>(c.frames));
    EXPECT_LT((seq.orientations[0] - Eigen::Matrix3d::Identity()).norm(), 1e-12) << "world = first camera";
    EXPECT_LT(seq.positions[0].norm(), 1e-9);
    double peak = 0, yaw_sum = 0;
    for (int k = 1; k < c.frames; ++k) {
      const Eigen::Matrix3d R = seq.orientations[k - 1].transpose() * seq.orientations[k];
      peak = std::max(peak, rotationAngleDeg(R));
      yaw_sum += std::atan2(R(0, 2), R(2, 2)) / kDeg;
      const double step = (seq.positions[k] - seq.positions[k - 1]).norm();
      EXPECT_GE(step, c.min_step_m) << c.preset << " frame " << k;
      EXPECT_LE(step, c.max_step_m) << c.preset << " frame " << k;
      EXPECT_NEAR(seq.stamps[k], k / c.rate_hz, 1e-12);
      EXPECT_LT((seq.orientations[k].transpose() * seq.orientations[k] - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    }
    std::printf("%-8s peak %.3f deg/frame, summed yaw %+.2f deg\n", c.preset.c_str(), peak, yaw_sum);
    EXPECT_GE(peak, c.min_peak_deg) << c.preset;
    EXPECT_LE(peak, c.max_peak_deg) << c.preset;
    if (c.preset == "drive") {
      // Camera heading at the middle of the right turn points right (positive yaw about +y).
      const Eigen::Vector3d forward = seq.orientations[30] * Eigen::Vector3d::UnitZ();
      EXPECT_GT(forward.x(), 0.3);
    }
  }
}

// The room presets' hand translation scales the still hand's jitter and nothing else: the same
// rotation, positions 20 times as far at 6 cm, other presets untouched; amounts beyond [0, 1] m are
// refused.
TEST(Renderer, HandTranslationScalesTheRoomPresetsTranslationOnly) {
  RenderSettings still, moving;
  ASSERT_TRUE(parsePreset("dim", &still.preset));
  still.rate_hz = 30.0;
  still.frames = 31;
  moving = still;
  moving.hand_translation_m = 0.06;
  double largest_step = 0.0;
  Eigen::Vector3d previous = Eigen::Vector3d::Zero();
  for (int k = 0; k < still.frames; ++k) {
    Eigen::Matrix3d R_still, R_moving;
    Eigen::Vector3d p_still, p_moving;
    presetPose(still, k / still.rate_hz, &R_still, &p_still);
    presetPose(moving, k / moving.rate_hz, &R_moving, &p_moving);
    EXPECT_EQ(R_moving, R_still) << "frame " << k;
    EXPECT_LT((p_moving - 20.0 * p_still).norm(), 1e-12) << "frame " << k;
    if (k > 0) largest_step = std::max(largest_step, (p_moving - previous).norm());
    previous = p_moving;
  }
  std::printf("hand moving by 6 cm: up to %.1f mm a frame at 30 Hz\n", 1e3 * largest_step);
  EXPECT_GT(largest_step, 0.005);
  EXPECT_LT(largest_step, 0.03);
  RenderSettings drive = still, drive_moving = moving;
  drive.preset = drive_moving.preset = RenderPreset::kDrive;
  Eigen::Matrix3d R_a, R_b;
  Eigen::Vector3d p_a, p_b;
  presetPose(drive, 1.0, &R_a, &p_a);
  presetPose(drive_moving, 1.0, &R_b, &p_b);
  EXPECT_EQ(p_a, p_b);
  for (const double bad : {-1e-3, 1.5, std::nan("")}) {
    moving.hand_translation_m = bad;
    EXPECT_THROW(presetPose(moving, 0.0, &R_a, &p_a), std::invalid_argument) << bad;
  }
}

/// Mean absolute difference of one row of two images [grey levels].
double rowDifference(const cv::Mat& a, const cv::Mat& b, int row) {
  return cv::norm(a.row(row), b.row(row), cv::NORM_L1) / a.cols;
}

TEST(Renderer, GlobalShutterFramesAreViewsFromTheirPose) {
  RenderSettings settings;
  settings.preset = RenderPreset::kHandheld;
  settings.rate_hz = 30.0;
  settings.frames = 3;
  settings.noise_sigma = 0.0;  // renderView draws other noise than a sequence's frame
  settings.setCentredCamera(160, 121, 125.0);
  ASSERT_EQ(settings.rolling_shutter_s, 0.0);  // the default
  const RenderedSequence seq = renderSequence(settings);
  for (size_t k = 0; k < seq.images.size(); ++k) {
    Eigen::Matrix3d orientation;
    Eigen::Vector3d position;
    presetPose(settings, seq.stamps[k], &orientation, &position);
    EXPECT_LT((orientation - seq.orientations[k]).norm(), 1e-15) << "frame " << k;
    EXPECT_LT((position - seq.positions[k]).norm(), 1e-15) << "frame " << k;
    const cv::Mat view = renderView(settings, seq.orientations[k], seq.positions[k]);
    EXPECT_EQ(cv::norm(seq.images[k], view, cv::NORM_INF), 0.0) << "frame " << k;
  }
}

TEST(Renderer, RollingShutterRowsAreSeenFromThePoseAtTheirTime) {
  RenderSettings settings;
  settings.preset = RenderPreset::kHandheld;
  settings.rate_hz = 30.0;
  settings.frames = 3;
  settings.noise_sigma = 0.0;
  settings.setCentredCamera(320, 241, 250.0);  // an odd height: row 120 is the middle row
  const RenderedSequence global = renderSequence(settings);
  settings.rolling_shutter_s = 0.028;
  const RenderedSequence rolling = renderSequence(settings);
  ASSERT_EQ(rolling.images.size(), 3u);
  const int last = settings.height - 1, middle = last / 2;
  for (size_t k = 0; k < rolling.images.size(); ++k) {
    // Stamps and poses are the middle row's, as with a global shutter.
    EXPECT_EQ(rolling.stamps[k], global.stamps[k]);
    EXPECT_LT((rolling.orientations[k] - global.orientations[k]).norm(), 1e-15);
    const cv::Mat& frame = rolling.images[k];
    auto viewAt = [&](double t) {
      Eigen::Matrix3d orientation;
      Eigen::Vector3d position;
      presetPose(settings, t, &orientation, &position);
      return renderView(settings, orientation, position);
    };
    const double t = rolling.stamps[k], half = 0.5 * settings.rolling_shutter_s;
    const cv::Mat top_view = viewAt(t - half), bottom_view = viewAt(t + half);
    EXPECT_EQ(rowDifference(frame, top_view, 0), 0.0) << "frame " << k;
    EXPECT_EQ(rowDifference(frame, bottom_view, last), 0.0) << "frame " << k;
    EXPECT_EQ(rowDifference(frame, global.images[k], middle), 0.0) << "frame " << k;
    // The camera turns during the read-out: the first and last rows are not the stamp's view's.
    const double top_moved = rowDifference(frame, global.images[k], 0);
    const double bottom_moved = rowDifference(frame, global.images[k], last);
    Eigen::Matrix3d bottom_orientation;
    Eigen::Vector3d bottom_position;
    presetPose(settings, t + half, &bottom_orientation, &bottom_position);
    const double angle_deg = rotationAngleDeg(global.orientations[k].transpose() * bottom_orientation);
    std::printf("frame %zu: %.3f deg turned in half the read-out; |top - global top| %.2f, |bottom - global "
                "bottom| %.2f grey levels\n",
                k, angle_deg, top_moved, bottom_moved);
    EXPECT_GT(angle_deg, 0.1) << "the hand-held camera turns";
    EXPECT_GT(top_moved, 2.0) << "frame " << k;
    EXPECT_GT(bottom_moved, 2.0) << "frame " << k;
  }
  // A read-out longer than the frame interval, negative or not finite is refused.
  for (const double bad : {1.0 / 30.0 + 1e-6, -1e-3, std::nan("")}) {
    settings.rolling_shutter_s = bad;
    EXPECT_THROW(renderSequence(settings), std::invalid_argument) << bad;
  }
  settings.rolling_shutter_s = 0.0;
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
  EXPECT_THROW(presetPose(settings, std::nan(""), &R, &p), std::invalid_argument);
}

TEST(Renderer, BadSettingsThrowInvalidArgument) {
  RenderSettings settings;
  EXPECT_FALSE(parsePreset("underwater", &settings.preset));
  EXPECT_EQ(settings.preset, RenderPreset::kDrive);  // untouched by the unknown name
  settings.width = 0;
  EXPECT_THROW(renderSequence(settings), std::invalid_argument);
  EXPECT_THROW(renderView(settings, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero()), std::invalid_argument);
  settings.width = 640;
  settings.height = 0;
  EXPECT_THROW(renderSequence(settings), std::invalid_argument);
  settings.height = 480;
  settings.frames = 0;
  EXPECT_THROW(renderSequence(settings), std::invalid_argument);
  settings.frames = 2;
  settings.fx = std::nan("");
  EXPECT_THROW(renderSequence(settings), std::invalid_argument);
  settings.fx = 500;
  settings.rate_hz = 0;
  EXPECT_THROW(renderSequence(settings), std::invalid_argument);
  settings.rate_hz = 10;
  EXPECT_THROW(renderView(settings, Eigen::Matrix3d::Constant(std::nan("")), Eigen::Vector3d::Zero()),
               std::invalid_argument);
}

TEST(ImageDegradation, EachDegradationDoesWhatItSays) {
  cv::Mat image(120, 160, CV_8UC1);
  cv::RNG(3).fill(image, cv::RNG::UNIFORM, 40, 216);
  cv::Scalar mean, deviation;
  cv::meanStdDev(image, mean, deviation);

  ImageDegradation none;
  EXPECT_FALSE(none.any());
  const cv::Mat same = degradeImage(image, none, 1);
  EXPECT_EQ(cv::norm(same, image, cv::NORM_INF), 0.0);

  // Contrast: the spread about the mean scales, the mean stays (within rounding).
  ImageDegradation dimmer;
  dimmer.contrast = 0.1;
  EXPECT_TRUE(dimmer.any());
  cv::Scalar dim_mean, dim_deviation;
  cv::meanStdDev(degradeImage(image, dimmer, 1), dim_mean, dim_deviation);
  EXPECT_NEAR(dim_mean[0], mean[0], 0.6);
  EXPECT_NEAR(dim_deviation[0], 0.1 * deviation[0], 0.6);

  // Noise: the difference from the image has the stated sigma and no offset; the same seed draws
  // the same noise, another seed other noise.
  ImageDegradation noisy;
  noisy.noise_sigma = 3.0;
  const cv::Mat a = degradeImage(image, noisy, 5), b = degradeImage(image, noisy, 5), c = degradeImage(image, noisy, 6);
  cv::Mat difference;
  cv::subtract(a, image, difference, cv::noArray(), CV_32F);
  cv::Scalar noise_mean, noise_deviation;
  cv::meanStdDev(difference, noise_mean, noise_deviation);
  EXPECT_NEAR(noise_mean[0], 0.0, 0.1);
  EXPECT_NEAR(noise_deviation[0], std::sqrt(9.0 + 1.0 / 12.0), 0.15);  // plus the rounding's
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_INF), 0.0);

  // Gain jitter: every grey level times one factor per image, within the jitter; the same seed
  // draws the same factor, other seeds others; the noise's draws stay as they were.
  ImageDegradation stepping;
  stepping.gain_jitter = 0.25;
  EXPECT_TRUE(stepping.any());
  std::vector<double> gains;
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    cv::Mat stepped = degradeImage(image, stepping, seed), expected;
    const double gain = cv::mean(stepped)[0] / mean[0];
    image.convertTo(expected, CV_8UC1, gain);  // rounds and saturates alike
    EXPECT_LE(cv::norm(stepped, expected, cv::NORM_INF), 1.0) << "seed " << seed;
    EXPECT_GE(gain, 0.75 - 0.01);
    EXPECT_LE(gain, 1.25 + 0.01);
    gains.push_back(gain);
  }
  EXPECT_GT(*std::max_element(gains.begin(), gains.end()) - *std::min_element(gains.begin(), gains.end()), 0.1);
  EXPECT_EQ(cv::norm(degradeImage(image, stepping, 3), degradeImage(image, stepping, 3), cv::NORM_INF), 0.0);
  // On a darker image, which neither end clips, the noise on top of the gain is the noise drawn
  // without it, up to rounding.
  cv::Mat darker;
  image.convertTo(darker, CV_8UC1, 0.6);
  ImageDegradation stepping_noisy = stepping;
  stepping_noisy.noise_sigma = 3.0;
  cv::Mat with_gain, gain_only, noise_alone;
  cv::subtract(degradeImage(darker, stepping_noisy, 5), degradeImage(darker, stepping, 5), with_gain, cv::noArray(),
               CV_32F);
  cv::subtract(degradeImage(darker, noisy, 5), darker, noise_alone, cv::noArray(), CV_32F);
  EXPECT_GT(cv::norm(degradeImage(darker, stepping, 5), darker, cv::NORM_INF), 1.0);  // the gain moved the levels
  EXPECT_LE(cv::norm(with_gain, noise_alone, cv::NORM_INF), 1.5 + 1e-6);

  // Stuck pixels: at most that many pixels turn white, the same ones whatever the seed, and only
  // they change.
  ImageDegradation defective;
  defective.stuck_pixels = 40;
  EXPECT_TRUE(defective.any());
  const cv::Mat stuck_a = degradeImage(image, defective, 1), stuck_b = degradeImage(image, defective, 2);
  EXPECT_EQ(cv::norm(stuck_a, stuck_b, cv::NORM_INF), 0.0);
  cv::Mat changed = stuck_a != image;
  EXPECT_GT(cv::countNonZero(changed), 30);  // 40 draws over 19 200 pixels, the image below 255
  EXPECT_LE(cv::countNonZero(changed), 40);
  cv::Mat white = stuck_a == 255;
  EXPECT_EQ(cv::countNonZero(changed & ~white), 0);

  // JPEG: a round trip at low quality changes the noise image, but keeps it close.
  ImageDegradation compressed;
  compressed.jpeg_quality = 20;
  const cv::Mat jpeg = degradeImage(image, compressed, 1);
  EXPECT_GT(cv::norm(jpeg, image, cv::NORM_INF), 0.0);
  EXPECT_LT(cv::norm(jpeg, image, cv::NORM_L1) / image.total(), 60.0);

  // The renderer's own validation is this one.
  ImageDegradation bad;
  bad.contrast = 0.0;
  EXPECT_THROW(degradeImage(image, bad, 1), std::invalid_argument);
  bad = ImageDegradation();
  bad.stuck_pixels = -1;
  EXPECT_THROW(checkDegradation(bad, "test"), std::invalid_argument);
  bad = ImageDegradation();
  bad.gain_jitter = 0.95;
  EXPECT_THROW(checkDegradation(bad, "test"), std::invalid_argument);
  bad = ImageDegradation();
  bad.jpeg_quality = 101;
  EXPECT_THROW(checkDegradation(bad, "test"), std::invalid_argument);
  bad = ImageDegradation();
  bad.blur_direction = Eigen::Vector2d(1.0, 1.0);
  EXPECT_THROW(checkDegradation(bad, "test"), std::invalid_argument);
  EXPECT_THROW(degradeImage(cv::Mat(4, 4, CV_16UC1, cv::Scalar(0)), none, 1), std::invalid_argument);
  RenderSettings settings;
  settings.contrast = -1.0;
  EXPECT_THROW(renderSequence(settings), std::invalid_argument);
}

TEST(Renderer, WriteKittiLayoutReportsErrors) {
  RenderedSequence empty;
  const std::string unused = test::makeTempDir("render_empty");
  EXPECT_THROW(writeKittiLayout(empty, unused), std::invalid_argument);
  std::filesystem::remove_all(unused);
  RenderedSequence one;
  one.images.push_back(cv::Mat(8, 8, CV_8UC1, cv::Scalar(7)));
  one.orientations.push_back(Eigen::Matrix3d::Identity());
  one.positions.push_back(Eigen::Vector3d::Zero());
  one.stamps.push_back(0.0);
  // A regular file where the folder should be.
  const std::string dir = test::makeTempDir("render_blocked");
  const std::string blocked = dir + "/file";
  { std::ofstream(blocked) << "x"; }
  EXPECT_THROW(writeKittiLayout(one, blocked + "/seq"), std::runtime_error);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace visual_gyro
