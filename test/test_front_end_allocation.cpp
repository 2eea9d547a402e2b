// The front end allocates nothing once its buffers have grown to a sequence's sizes: every call
// with an output argument (detection, description, prediction, global and guided matching,
// sub-pixel refinement, tracking) reuses the capacity of the frames before. Counted through this
// binary's global operator new, which every std::vector and std::string allocation goes through.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <new>

#include "test_support.h"
#include "visual_gyro/feature_front_end.h"
#include "visual_gyro/renderer.h"

namespace {
std::atomic<bool> counting{false};
std::atomic<long> allocations{0};
}  // namespace

void* operator new(std::size_t size) {
  if (counting.load(std::memory_order_relaxed)) allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace vg = visual_gyro;

TEST(FrontEndAllocation, SteadyStateAllocatesNothing) {
  vg::RenderSettings scene;
  scene.preset = vg::RenderPreset::kDim;
  scene.frames = 6;
  scene.blur_px = 3.0;
  scene.jpeg_quality = 75;
  const vg::RenderedSequence sequence = vg::renderSequence(scene);
  const vg::CameraModel camera = vg::test::cameraOf(scene);

  vg::FrontEndSettings settings;
  settings.subpixel_refinement = true;
  settings.track_unmatched = true;
  const vg::FeatureFrontEnd front_end(settings);
  std::vector<cv::Point2f> corners;
  vg::FrameFeatures previous, current;
  std::vector<Eigen::Vector3d> bearings;
  vg::MatchPrediction prediction;
  std::vector<vg::FeatureMatch> matches;
  std::vector<vg::TrackedCorner> tracks;
  long calls_with_output = 0;
  const auto runSequence = [&]() {
    for (size_t k = 0; k < sequence.images.size(); ++k) {
      const cv::Mat& image = sequence.images[k];
      front_end.detect(image, &corners);
      front_end.describe(image, corners, &current);
      if (k > 0) {
        const Eigen::Matrix3d truth = sequence.orientations[k - 1].transpose() * sequence.orientations[k];
        bearings.resize(previous.keypoints.size());
        for (size_t i = 0; i < bearings.size(); ++i)
          bearings[i] = camera.bearing(previous.keypoints[i].x, previous.keypoints[i].y);
        front_end.match(previous, current, &matches);
        front_end.predict(camera, truth, 0.001, bearings, &prediction);
        front_end.matchGuided(previous, current, prediction, &matches);
        front_end.refineMatches(sequence.images[k - 1], image, previous, current, &matches);
        front_end.trackUnmatched(sequence.images[k - 1], image, previous, current, matches, &tracks);
        calls_with_output += tracks.empty() ? 0 : 1;
      }
      std::swap(previous, current);
    }
  };
  runSequence();  // the buffers grow to this sequence's sizes
  ASSERT_GT(calls_with_output, 0) << "nothing was tracked: the test would not exercise tracking";
  counting = true;
  runSequence();  // the same frames again: every size has been seen
  counting = false;
  std::printf("allocations while replaying %zu frames: %ld\n", sequence.images.size(), allocations.load());
  EXPECT_EQ(allocations.load(), 0);
}
