// Offline and through ROS, the same figures: a rendered sequence with one black (featureless)
// image goes through `evaluate --method vote` and, as a bag played frame by frame, through the node
// (offline_equivalence.test); the frame count, the invalid frames, the rotation error RMSE and
// maximum must agree to 1e-4 deg (an invalid frame scores as the identity rotation in both).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

#include "bag_tools.h"
#include "frame_player.h"
#include "ros_test_support.h"
#include "test_support.h"
#include "visual_gyro/sequence.h"

namespace {

namespace bt = visual_gyro::bag_tools;
namespace vt = visual_gyro::test;

/// The last line of `output` (evaluate's JSON object).
std::string lastLine(const std::string& output) {
  std::istringstream in(output);
  std::string line, last;
  while (std::getline(in, line))
    if (!line.empty()) last = line;
  return last;
}

TEST(OfflineEquivalence, SameFramesAndRotationErrorsWithAnInvalidFrame) {
  const std::string dir = vt::makeTempDir("equivalence");
  const std::string seq_dir = dir + "/handheld";
  int status = 0;
  const std::string render = vt::runCommand(std::string(VISUAL_GYRO_RENDER) +
                                                " --preset handheld --frames 20 --width 320 --height 240 "
                                                "--focal 250 --out " + seq_dir,
                                            &status);
  ASSERT_EQ(status, 0) << render;
  visual_gyro::Sequence sequence = visual_gyro::loadSequence(seq_dir);
  ASSERT_EQ(sequence.image_paths.size(), 20u);
  // A black image: no features, so its pair and the next one give no valid estimate.
  const cv::Mat first = cv::imread(sequence.image_paths[0], cv::IMREAD_GRAYSCALE);
  ASSERT_TRUE(cv::imwrite(sequence.image_paths[8], cv::Mat::zeros(first.size(), CV_8UC1)));

  const std::string evaluated =
      vt::runCommand(std::string(VISUAL_GYRO_EVALUATE) + " " + seq_dir + " --method vote --quiet", &status);
  ASSERT_EQ(status, 0) << evaluated;
  const std::string json = lastLine(evaluated);
  std::printf("evaluate: %s\n", json.c_str());

  const std::string bag_path = dir + "/handheld.bag";
  sequence = visual_gyro::loadSequence(seq_dir);
  bt::writeSequenceBag(sequence, bag_path, bt::BagWriteOptions());
  const bt::BagContents bag = bt::readSequenceBag(bag_path);
  visual_gyro::frame_player::PlayerOptions options;
  options.frame_timeout = 20.0;
  const auto report = visual_gyro::frame_player::playFrames(bag, options);
  ASSERT_TRUE(report.ok) << report.error;
  ASSERT_EQ(report.processed, 20) << "the node dropped frames";
  const bt::OutputSummary ros = bt::evaluateOutputs(report.rotations, static_cast<int>(report.imus.size()), bag,
                                                    "handheld");
  std::printf("ROS:      %s\n", ros.json().c_str());

  EXPECT_EQ(ros.accuracy.frames, static_cast<int>(vt::jsonNumber(json, "frames")));
  EXPECT_EQ(ros.accuracy.invalid, static_cast<int>(vt::jsonNumber(json, "invalid")));
  EXPECT_GE(ros.accuracy.invalid, 1) << "the black image gave no invalid frame";
  EXPECT_EQ(ros.accuracy.with_truth, ros.accuracy.frames);
  EXPECT_NEAR(ros.accuracy.rot_rmse_deg, vt::jsonNumber(json, "rot_rmse_deg"), 1e-4);
  EXPECT_NEAR(ros.accuracy.rot_max_deg, vt::jsonNumber(json, "rot_max_deg"), 1e-4);
  std::filesystem::remove_all(dir);
}

}  // namespace

int main(int argc, char** argv) {
  return visual_gyro::ros_test::runRosTests(argc, argv, "test_offline_equivalence", 1, [] { return RUN_ALL_TESTS(); });
}
