// Front end for hard footage: guided matching against global matching on a rendered pair with a
// known rotation, the fallback to global matching after a wrong prior, the search covering the
// parallax of near structure, adaptive FAST thresholds on
// low-contrast texture, tracking of unmatched corners, the renderer's degradations and the
// settings' single source of truth.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include <opencv2/imgproc.hpp>

#include "test_support.h"
#include "visual_gyro/feature_front_end.h"
#include "visual_gyro/renderer.h"
#include "visual_gyro/visual_gyro.h"

namespace vg = visual_gyro;

namespace {

constexpr double kDeg = M_PI / 180.0;

using vg::test::cameraOf;

vg::RenderSettings roomScene() { return vg::test::handheldRoom(480, 360, 380.0); }

Eigen::Matrix3d yawPitch(double yaw_deg, double pitch_deg) {
  return (Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(pitch_deg * kDeg, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

/// True when match m agrees with the rotation `truth` (b_prev ~ R b_cur) to within 1.5 px.
bool correct(const vg::CameraModel& camera, const Eigen::Matrix3d& truth, const vg::FrameFeatures& previous,
             const vg::FrameFeatures& current, const vg::FeatureMatch& m) {
  const cv::Point2f p = previous.keypoints[m.previous], q = current.keypoints[m.current];
  const Eigen::Vector2d predicted = camera.project(truth.transpose() * camera.bearing(p.x, p.y));
  return std::hypot(predicted.x() - q.x, predicted.y() - q.y) <= 1.5;
}

/// Two images' features and their global matches.
struct MatchedPair {
  vg::FrameFeatures previous, current;
  std::vector<vg::FeatureMatch> matches;
};

MatchedPair describeAndMatch(const vg::FeatureFrontEnd& front_end, const cv::Mat& image0, const cv::Mat& image1) {
  MatchedPair pair;
  pair.previous = front_end.describe(image0, front_end.detect(image0));
  pair.current = front_end.describe(image1, front_end.detect(image1));
  front_end.match(pair.previous, pair.current, &pair.matches);
  return pair;
}

}  // namespace

// Guided matching with the true rotation finds every correct match that global matching finds:
// a correct global match is the mutual best over all descriptors, so it is also the mutual best in
// the windows, and the second best in a window is no closer than the global one (ratio test).
TEST(GuidedMatching, FindsTheCorrectMatchesOfGlobalMatching) {
  const vg::RenderSettings scene = roomScene();
  const vg::CameraModel camera = cameraOf(scene);
  const Eigen::Matrix3d R0 = yawPitch(0.0, 0.0), R1 = yawPitch(2.5, -1.0);
  const Eigen::Matrix3d truth = R0.transpose() * R1;
  const cv::Mat image0 = vg::renderView(scene, R0, Eigen::Vector3d::Zero());
  const cv::Mat image1 = vg::renderView(scene, R1, Eigen::Vector3d::Zero());

  const vg::FeatureFrontEnd front_end;
  const vg::FrameFeatures previous = front_end.describe(image0, front_end.detect(image0));
  const vg::FrameFeatures current = front_end.describe(image1, front_end.detect(image1));
  std::vector<vg::FeatureMatch> global, guided;
  front_end.match(previous, current, &global);

  std::vector<Eigen::Vector3d> bearings;
  for (const cv::Point2f& p : previous.keypoints) bearings.push_back(camera.bearing(p.x, p.y));
  vg::MatchPrediction prediction;
  front_end.predict(camera, truth, 0.0, bearings, &prediction);
  front_end.matchGuided(previous, current, prediction, &guided);

  std::set<std::pair<int, int>> guided_pairs;
  size_t guided_correct = 0;
  for (const vg::FeatureMatch& m : guided) {
    guided_pairs.insert({m.previous, m.current});
    EXPECT_EQ(m.distance, vg::hammingDistance(previous.descriptors[m.previous], current.descriptors[m.current]));
    if (correct(camera, truth, previous, current, m)) ++guided_correct;
  }
  size_t global_correct = 0, found = 0;
  for (const vg::FeatureMatch& m : global) {
    if (!correct(camera, truth, previous, current, m)) continue;
    ++global_correct;
    if (guided_pairs.count({m.previous, m.current})) ++found;
    else ADD_FAILURE() << "correct global match " << m.previous << " -> " << m.current << " not found guided";
  }
  std::printf("global: %zu matches, %zu correct; guided: %zu matches, %zu correct, %zu of global's correct\n",
              global.size(), global_correct, guided.size(), guided_correct, found);
  EXPECT_GE(global_correct, 300u);
  EXPECT_EQ(found, global_correct);
  EXPECT_GE(guided_correct, global_correct);
}

TEST(GuidedMatching, PredictionFollowsTheCameraModelAndDropsPointsLeavingTheView) {
  // Distorted camera: the prediction goes through the distortion model.
  const vg::CameraModel camera(400.0, 400.0, 319.5, 239.5, 640, 480, vg::DistortionModel::kPlumbBob,
                               {-0.28, 0.07, 0.0002, 0.00002});
  vg::FrontEndSettings settings;
  settings.guided_radius_px = 10.0;
  settings.guided_radius_growth = 0.0;
  const vg::FeatureFrontEnd front_end(settings);
  const Eigen::Matrix3d R = yawPitch(3.0, 1.0);
  const std::vector<Eigen::Vector3d> bearings{camera.bearing(100.0, 80.0), camera.bearing(600.0, 400.0),
                                              camera.bearing(320.0, 240.0)};
  vg::MatchPrediction prediction;
  front_end.predict(camera, R, 0.01, bearings, &prediction);
  ASSERT_EQ(prediction.positions.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    const Eigen::Vector2d expected = camera.project(R.transpose() * bearings[i]);
    EXPECT_NEAR(prediction.positions[i].x, expected.x(), 1e-3);
    EXPECT_NEAR(prediction.positions[i].y, expected.y(), 1e-3);
    // Radius: 10 px plus the uncertainty (0.01 rad at 400 px focal length).
    EXPECT_NEAR(prediction.radii[i], 14.0, 1e-4);
  }
  // A 90 degree turn takes the centre out of the view: no search for it.
  front_end.predict(camera, yawPitch(90.0, 0.0), 0.0, bearings, &prediction);
  EXPECT_LT(prediction.radii[2], 0.0f);

  EXPECT_THROW(front_end.predict(camera, Eigen::Matrix3d::Constant(NAN), 0.0, bearings, &prediction),
               std::invalid_argument);
  EXPECT_THROW(front_end.predict(camera, R, -1.0, bearings, &prediction), std::invalid_argument);
  vg::FrameFeatures features;
  features.keypoints.resize(3);
  features.descriptors.resize(3);
  vg::MatchPrediction short_prediction;
  std::vector<vg::FeatureMatch> matches;
  EXPECT_THROW(front_end.matchGuided(features, features, short_prediction, &matches), std::invalid_argument);
}

// The pipeline matches guided once it has a prior, falls back to global matching when the prior is
// wrong (the camera turns back sharply), and still estimates the true rotation.
TEST(GuidedMatching, WrongPriorFallsBackToGlobalMatching) {
  const vg::RenderSettings scene = roomScene();
  vg::VisualGyroSettings settings;
  settings.estimator.backend = vg::BackendChoice::kCpu;
  vg::VisualGyro gyro(cameraOf(scene), settings);
  const double yaws[] = {0.0, 2.0, 4.0, 6.0, -4.0};  // +2 deg a frame, then -10 deg
  std::vector<vg::FrameResult> results;
  for (int k = 0; k < 5; ++k) {
    results.push_back(gyro.processFrame(vg::renderView(scene, yawPitch(yaws[k], 0.0), Eigen::Vector3d::Zero()),
                                        1.0 + 0.05 * k));
  }
  EXPECT_EQ(results[0].matching, vg::PairMatching::kNone);
  EXPECT_EQ(results[1].matching, vg::PairMatching::kGlobal);  // no prior yet
  EXPECT_EQ(results[2].matching, vg::PairMatching::kGuided);
  EXPECT_EQ(results[3].matching, vg::PairMatching::kGuided);
  EXPECT_EQ(results[4].matching, vg::PairMatching::kGlobalFallback);  // the prior says +2 deg, the camera turned -10
  for (int k = 1; k < 5; ++k) {
    ASSERT_TRUE(results[k].hasEstimate()) << "frame " << k << ": " << results[k].reason;
    const Eigen::Matrix3d truth = yawPitch(yaws[k - 1], 0.0).transpose() * yawPitch(yaws[k], 0.0);
    EXPECT_LT(vg::rotationAngleBetween(results[k].rotation.rotation, truth), 0.05 * kDeg) << "frame " << k;
    EXPECT_GE(results[k].previous_bearings.size(), 200u) << "frame " << k;
  }
  // After a reset there is no prior: global again. matching = global never guides.
  gyro.reset();
  gyro.processFrame(vg::renderView(scene, yawPitch(0.0, 0.0), Eigen::Vector3d::Zero()), 2.0);
  EXPECT_EQ(gyro.processFrame(vg::renderView(scene, yawPitch(2.0, 0.0), Eigen::Vector3d::Zero()), 2.05).matching,
            vg::PairMatching::kGlobal);
  settings.front_end.matching = vg::MatchingMode::kGlobal;
  gyro.setSettings(settings);
  EXPECT_EQ(gyro.processFrame(vg::renderView(scene, yawPitch(4.0, 0.0), Eigen::Vector3d::Zero()), 2.1).matching,
            vg::PairMatching::kGlobal);
}

// Near structure under sideways motion: points move from where the rotation puts them by their
// parallax, tens of pixels here, more than the base search radius. Once a pair has measured it, the
// guided search covers it and finds the near points' matches as global matching does (they are what
// tells rotation from translation); a search sized for the rotation alone would lose them.
TEST(GuidedMatching, SearchCoversTheParallaxOfTheLastPair) {
  vg::RenderSettings scene;
  scene.preset = vg::RenderPreset::kDroneNear;
  scene.setCentredCamera(480, 360, 380.0);
  vg::VisualGyroSettings guided_settings = vg::test::cpuSettings(), global_settings = guided_settings;
  global_settings.front_end.matching = vg::MatchingMode::kGlobal;
  vg::VisualGyro guided(cameraOf(scene), guided_settings), global(cameraOf(scene), global_settings);
  constexpr double kStepM = 0.2;  // sideways per frame
  int guided_matches = 0, global_matches = 0;
  for (int k = 0; k < 6; ++k) {
    const cv::Mat image =
        vg::renderView(scene, yawPitch(0.5 * k, 0.0), Eigen::Vector3d(kStepM * k, 0.0, 0.0));
    const vg::FrameResult a = guided.processFrame(image, 1.0 + 0.05 * k);
    const vg::FrameResult b = global.processFrame(image, 1.0 + 0.05 * k);
    if (k < 3) continue;  // the first pairs settle the prior and the measured parallax
    ASSERT_TRUE(a.hasEstimate()) << "frame " << k << ": " << a.reason;
    EXPECT_EQ(a.matching, vg::PairMatching::kGuided) << "frame " << k;
    guided_matches += static_cast<int>(a.previous_bearings.size()) - a.tracked;
    global_matches += static_cast<int>(b.previous_bearings.size()) - b.tracked;
  }
  std::printf("descriptor matches of frames 3-5: guided %d, global %d\n", guided_matches, global_matches);
  EXPECT_GE(guided_matches, 0.95 * global_matches);
}

// Adaptive detection: a low-contrast half of the image, without a corner at the normal FAST
// threshold, gets corners from the lower per-cell threshold once the strong corners cannot fill
// the budget; while they can, the selection is that of the fixed threshold.
TEST(AdaptiveDetection, LowContrastCellsGetCornersAtTheFloorThreshold) {
  vg::RenderSettings scene = roomScene();
  scene.setCentredCamera(640, 480, 500.0);
  cv::Mat image = vg::renderView(scene, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  cv::Mat right = image(cv::Rect(320, 0, 320, 480));
  right.convertTo(right, CV_8U, 0.2, 100);  // a fifth of the contrast

  auto rightCount = [](const std::vector<cv::Point2f>& corners) {
    return static_cast<long>(
        std::count_if(corners.begin(), corners.end(), [](const cv::Point2f& p) { return p.x >= 320; }));
  };
  vg::FrontEndSettings fixed;
  fixed.track_unmatched = false;  // without tracking the floor pass depends on the budget alone
  fixed.max_features = 4000;  // more than the strong corners: the budget is not filled
  fixed.min_fast_threshold = fixed.fast_threshold;  // off
  vg::FrontEndSettings adaptive = fixed;
  adaptive.min_fast_threshold = vg::FrontEndSettings().min_fast_threshold;
  const std::vector<cv::Point2f> before = vg::FeatureFrontEnd(fixed).detect(image);
  const std::vector<cv::Point2f> after = vg::FeatureFrontEnd(adaptive).detect(image);
  std::printf("corners in the low-contrast half: fixed threshold %ld, adaptive %ld (of %zu / %zu)\n",
              rightCount(before), rightCount(after), before.size(), after.size());
  ASSERT_LT(before.size(), 4000u) << "the strong corners fill the budget; the test needs them not to";
  EXPECT_LT(rightCount(before), 50);
  // The 24 cells of that half (share 4000 / 48 = 83 each) get a good part of their shares.
  EXPECT_GE(rightCount(after), 24 * 40);
  EXPECT_LE(after.size(), 4000u);
  // Every strong corner is still selected (the budget is not full).
  std::set<std::pair<float, float>> selected;
  for (const cv::Point2f& p : after) selected.insert({p.x, p.y});
  for (const cv::Point2f& p : before) EXPECT_TRUE(selected.count({p.x, p.y})) << p;

  // With the default budget (and no tracking) the strong corners fill it: exactly the fixed
  // threshold's corners.
  vg::FrontEndSettings fixed_default, adaptive_default;
  fixed_default.track_unmatched = adaptive_default.track_unmatched = false;
  fixed_default.min_fast_threshold = fixed_default.fast_threshold;
  const std::vector<cv::Point2f> full_fixed = vg::FeatureFrontEnd(fixed_default).detect(image);
  ASSERT_EQ(full_fixed.size(), static_cast<size_t>(fixed_default.max_features));
  EXPECT_EQ(vg::FeatureFrontEnd(adaptive_default).detect(image), full_fixed);

  // With tracking, the short cells get the floor pass even when the strong corners fill the
  // budget: corners there no longer need FAST to find them again in the next frame.
  vg::FrontEndSettings tracking_default;
  tracking_default.track_unmatched = true;
  const std::vector<cv::Point2f> full_tracking = vg::FeatureFrontEnd(tracking_default).detect(image);
  std::printf("default budget, corners in the low-contrast half: %ld without tracking, %ld with\n",
              rightCount(full_fixed), rightCount(full_tracking));
  EXPECT_EQ(full_tracking.size(), static_cast<size_t>(tracking_default.max_features));
  EXPECT_GE(rightCount(full_tracking), rightCount(full_fixed) + 24 * 15);
}

// With tracking the detector skips the strong pass in cells the last frame found short: that
// guess saves time only. Whatever frame came before, every frame's corners are those a fresh
// front end finds, including when the guess is wrong both ways (cells short in one frame and full
// in the next, and the reverse).
TEST(AdaptiveDetection, CornersDoNotDependOnThePreviousFrame) {
  // Texture with corners everywhere: every cell holds its share at the normal threshold.
  cv::Mat full(480, 640, CV_8UC1);
  cv::RNG rng(7);
  rng.fill(full, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(full, full, cv::Size(7, 7), 1.5);
  cv::Mat left_dim = full.clone(), right_dim = full.clone();
  cv::Mat half = left_dim(cv::Rect(0, 0, 320, 480));
  half.convertTo(half, CV_8U, 0.2, 100);
  half = right_dim(cv::Rect(320, 0, 320, 480));
  half.convertTo(half, CV_8U, 0.2, 100);
  vg::RenderSettings scene = roomScene();
  scene.setCentredCamera(640, 480, 500.0);
  const cv::Mat room = vg::renderView(scene, yawPitch(3.0, 1.0), Eigen::Vector3d::Zero());
  const std::vector<cv::Mat> frames = {full, left_dim, right_dim, left_dim, room, right_dim, full, room};

  // The default budget, and a larger one that the strong corners of a half-dim frame do not fill
  // (weak corners are selected too, so a cell guessed short that holds its share of 41 must give
  // its strong corners only).
  for (const int budget : {vg::FrontEndSettings().max_features, 2000}) {
    vg::FrontEndSettings settings;
    settings.track_unmatched = true;
    settings.max_features = budget;
    const vg::FeatureFrontEnd running(settings);
    for (size_t k = 0; k < frames.size(); ++k) {
      const std::vector<cv::Point2f> corners = running.detect(frames[k]);
      const std::vector<cv::Point2f> fresh = vg::FeatureFrontEnd(settings).detect(frames[k]);
      EXPECT_EQ(corners, fresh) << "budget " << budget << ", frame " << k;
      if (budget == vg::FrontEndSettings().max_features) EXPECT_EQ(corners.size(), static_cast<size_t>(budget));
    }
  }
}

// Tracking: on a dim, JPEG-compressed room FAST finds many low-contrast corners in only one of two
// frames, so they cannot match; tracking finds them where the true rotation puts them, to a
// fraction of a pixel, and never a corner that already has a match.
TEST(Tracking, FindsUnmatchedCornersWhereTheRotationPutsThem) {
  vg::RenderSettings scene;
  scene.preset = vg::RenderPreset::kDim;
  scene.jpeg_quality = 75;
  const vg::CameraModel camera = cameraOf(scene);
  const Eigen::Matrix3d R0 = yawPitch(0.0, 0.0), R1 = yawPitch(1.0, -0.5);
  const Eigen::Matrix3d truth = R0.transpose() * R1;
  const cv::Mat image0 = vg::renderView(scene, R0, Eigen::Vector3d::Zero());
  const cv::Mat image1 = vg::renderView(scene, R1, Eigen::Vector3d::Zero());

  vg::FrontEndSettings settings;
  settings.subpixel_refinement = true;
  settings.track_unmatched = true;
  const vg::FeatureFrontEnd front_end(settings);
  MatchedPair pair = describeAndMatch(front_end, image0, image1);
  const vg::FrameFeatures &previous = pair.previous, &current = pair.current;
  std::vector<vg::FeatureMatch>& matches = pair.matches;
  front_end.refineMatches(image0, image1, previous, current, &matches);
  std::vector<vg::TrackedCorner> tracks;
  front_end.trackUnmatched(image0, image1, previous, current, matches, &tracks);

  std::set<int> matched, tracked;
  for (const vg::FeatureMatch& m : matches) matched.insert(m.previous);
  std::vector<double> errors;
  for (const vg::TrackedCorner& t : tracks) {
    EXPECT_EQ(matched.count(t.previous), 0u) << "corner " << t.previous << " is matched and tracked";
    EXPECT_TRUE(tracked.insert(t.previous).second) << "corner " << t.previous << " tracked twice";
    const cv::Point2f p = previous.keypoints[t.previous];
    const Eigen::Vector2d expected = camera.project(truth.transpose() * camera.bearing(p.x, p.y));
    errors.push_back(std::hypot(expected.x() - t.position.x, expected.y() - t.position.y));
  }
  ASSERT_FALSE(errors.empty());
  // The yardstick: the descriptor matches' own sub-pixel positions on the same pair (2 grey levels
  // of noise on at most 30 of contrast, and JPEG, limit both to a few tenths of a pixel).
  std::vector<double> match_errors;
  for (const vg::FeatureMatch& m : matches) {
    const cv::Point2f p = previous.keypoints[m.previous], q = current.keypoints[m.current] + m.offset;
    const Eigen::Vector2d expected = camera.project(truth.transpose() * camera.bearing(p.x, p.y));
    match_errors.push_back(std::hypot(expected.x() - q.x, expected.y() - q.y));
  }
  std::sort(errors.begin(), errors.end());
  std::sort(match_errors.begin(), match_errors.end());
  const auto quantile = [](const std::vector<double>& sorted, int percent) {
    return sorted[sorted.size() * percent / 100];
  };
  std::printf("%zu corners, %zu matches, %zu tracked; position error median / 95 %%: tracked %.3f / %.3f px, "
              "matches %.3f / %.3f px\n",
              previous.keypoints.size(), matches.size(), tracks.size(), quantile(errors, 50), quantile(errors, 95),
              quantile(match_errors, 50), quantile(match_errors, 95));
  // More corners tracked than matched, as precise as the matches, and a wrong track rarer than a
  // wrong match (the correlation test).
  EXPECT_GE(tracks.size(), matches.size());
  EXPECT_LT(quantile(errors, 50), 1.2 * quantile(match_errors, 50));
  EXPECT_LT(quantile(errors, 95), 1.0);
  EXPECT_LT(quantile(errors, 95), quantile(match_errors, 95));

  // Through the pipeline: the tracked corners join the matches and the rotation stays accurate.
  vg::VisualGyroSettings pipeline = vg::test::cpuSettings();
  pipeline.front_end = settings;
  for (const bool track : {false, true}) {
    pipeline.front_end.track_unmatched = track;
    vg::VisualGyro gyro(camera, pipeline);
    gyro.processFrame(image0, 1.0);
    const vg::FrameResult result = gyro.processFrame(image1, 1.05);
    ASSERT_TRUE(result.hasEstimate()) << result.reason;
    const size_t expected_pairs = track ? matches.size() + tracks.size() : matches.size();
    EXPECT_EQ(result.previous_bearings.size(), expected_pairs) << "tracking " << track;
    EXPECT_EQ(result.current_pixels.size(), expected_pairs);
    EXPECT_LT(vg::rotationAngleBetween(result.rotation.rotation, truth), 0.02 * kDeg) << "tracking " << track;
  }
}

TEST(Tracking, OffOrWithoutMatchesTracksNothingAndBadInputThrows) {
  vg::RenderSettings scene = roomScene();
  const cv::Mat image0 = vg::renderView(scene, yawPitch(0.0, 0.0), Eigen::Vector3d::Zero());
  const cv::Mat image1 = vg::renderView(scene, yawPitch(1.0, 0.0), Eigen::Vector3d::Zero());
  vg::FrontEndSettings settings;
  settings.track_unmatched = true;
  const vg::FeatureFrontEnd tracking(settings);
  const MatchedPair pair = describeAndMatch(tracking, image0, image1);
  const vg::FrameFeatures &previous = pair.previous, &current = pair.current;
  const std::vector<vg::FeatureMatch>& matches = pair.matches;
  ASSERT_GE(matches.size(), 10u);
  std::vector<vg::TrackedCorner> tracks(5);
  tracking.trackUnmatched(image0, image1, previous, current, matches, &tracks);
  EXPECT_FALSE(tracks.empty());

  // Off: emptied, whatever the matches.
  settings.track_unmatched = false;
  tracks.assign(5, vg::TrackedCorner());
  vg::FeatureFrontEnd(settings).trackUnmatched(image0, image1, previous, current, matches, &tracks);
  EXPECT_TRUE(tracks.empty());
  // Two matches say nothing about how the image moved: nothing tracked.
  const std::vector<vg::FeatureMatch> two(matches.begin(), matches.begin() + 2);
  tracks.assign(5, vg::TrackedCorner());
  tracking.trackUnmatched(image0, image1, previous, current, two, &tracks);
  EXPECT_TRUE(tracks.empty());

  cv::Mat small;
  cv::resize(image1, small, cv::Size(), 0.5, 0.5);
  EXPECT_THROW(tracking.trackUnmatched(image0, small, previous, current, matches, &tracks), std::invalid_argument);
  cv::Mat colour;
  cv::cvtColor(image1, colour, cv::COLOR_GRAY2BGR);
  EXPECT_THROW(tracking.trackUnmatched(image0, colour, previous, current, matches, &tracks), std::invalid_argument);
  EXPECT_THROW(tracking.trackUnmatched(image0, cv::Mat(), previous, current, matches, &tracks), std::invalid_argument);
  std::vector<vg::FeatureMatch> dangling = matches;
  dangling[0].current = static_cast<int>(current.keypoints.size());
  EXPECT_THROW(tracking.trackUnmatched(image0, image1, previous, current, dangling, &tracks), std::invalid_argument);
  dangling[0] = matches[0];
  dangling[1].previous = -1;
  EXPECT_THROW(tracking.trackUnmatched(image0, image1, previous, current, dangling, &tracks), std::invalid_argument);
  vg::FrameFeatures misaligned = current;
  misaligned.descriptors.pop_back();
  EXPECT_THROW(tracking.trackUnmatched(image0, image1, previous, misaligned, matches, &tracks), std::invalid_argument);
  settings.track_unmatched = true;
  settings.min_track_correlation = 2.0;
  EXPECT_THROW(vg::FeatureFrontEnd(settings).trackUnmatched(image0, image1, previous, current, matches, &tracks),
               std::invalid_argument);
}

TEST(RendererDegradations, ContrastBlurAndJpegChangeTheImageAsDocumented) {
  vg::RenderSettings s = roomScene();
  s.noise_sigma = 0.0;
  const cv::Mat clean = vg::renderView(s, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  cv::Scalar mean, stddev;
  cv::meanStdDev(clean, mean, stddev);

  s.contrast = 0.25;
  const cv::Mat low = vg::renderView(s, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  cv::Scalar low_mean, low_stddev;
  cv::meanStdDev(low, low_mean, low_stddev);
  EXPECT_NEAR(low_mean[0], mean[0], 1.0);
  EXPECT_NEAR(low_stddev[0], 0.25 * stddev[0], 0.05 * stddev[0] + 0.5);

  // renderView blurs along +x: horizontal gradients drop, vertical ones much less.
  s.contrast = 1.0;
  s.blur_px = 6.0;
  const cv::Mat blurred = vg::renderView(s, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  auto gradient = [](const cv::Mat& image, int dx, int dy) {
    cv::Mat g;
    cv::Sobel(image, g, CV_32F, dx, dy);
    return cv::mean(cv::abs(g))[0];
  };
  const double along = gradient(blurred, 1, 0) / gradient(clean, 1, 0);
  const double across = gradient(blurred, 0, 1) / gradient(clean, 0, 1);
  std::printf("6 px blur along x: x gradients x%.2f, y gradients x%.2f\n", along, across);
  EXPECT_LT(along, 0.75);
  EXPECT_GT(across, 0.8);
  EXPECT_LT(along, across - 0.15);

  s.blur_px = 0.0;
  s.jpeg_quality = 20;
  const cv::Mat jpeg = vg::renderView(s, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  ASSERT_EQ(jpeg.type(), CV_8UC1);
  ASSERT_EQ(jpeg.size(), clean.size());
  const double change = cv::norm(jpeg, clean, cv::NORM_L1) / clean.total();
  EXPECT_GT(change, 0.5);
  EXPECT_LT(change, 10.0);

  const std::vector<std::function<void(vg::RenderSettings*)>> bad_settings{
      [](vg::RenderSettings* r) { r->contrast = 0.0; }, [](vg::RenderSettings* r) { r->blur_px = -1.0; },
      [](vg::RenderSettings* r) { r->jpeg_quality = 101; }};
  for (const auto& bad : bad_settings) {
    vg::RenderSettings b = roomScene();
    bad(&b);
    EXPECT_THROW(vg::renderView(b, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero()), std::invalid_argument);
  }
}

TEST(RendererDegradations, DimPresetStaysWithinThirtyGreyLevels) {
  vg::RenderSettings s;
  s.preset = vg::RenderPreset::kDim;
  s.frames = 3;
  s.rate_hz = 30.0;
  s.noise_sigma = 0.0;
  const vg::RenderedSequence seq = vg::renderSequence(s);
  ASSERT_EQ(seq.images.size(), 3u);
  for (const cv::Mat& image : seq.images) {
    double lo = 0, hi = 0;
    cv::minMaxLoc(image, &lo, &hi);
    EXPECT_LE(hi - lo, 30.0);
    EXPECT_GE(hi - lo, 10.0);  // not blank either
  }
  // The dim room moves like the hand-held one.
  vg::RenderSettings h = s;
  h.preset = vg::RenderPreset::kHandheld;
  const vg::RenderedSequence hand = vg::renderSequence(h);
  for (size_t k = 0; k < 3; ++k) EXPECT_TRUE(seq.orientations[k].isApprox(hand.orientations[k]));
}

