// The inputs and the estimator-level rule of the stand-alone GPU tools (cuda/standalone/): the
// bearing file format, the CPU/CUDA estimator comparison (runs everywhere against itself and
// against corrupted runs; against CUDA only where a device works), and that a run from an exported
// bearing file reproduces evaluate's own figures, so the GPU machine (no ROS, no OpenCV) measures
// exactly what `make eval` reports.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "bearing_file.h"
#include "../cuda/standalone/estimator_compare.h"
#include "test_support.h"
#include "visual_gyro/rotation_estimator.h"

namespace visual_gyro {
namespace {

using bearings::BearingFrame;

std::vector<BearingFrame> syntheticFrames(int count, uint32_t matches, double forward) {
  std::vector<BearingFrame> frames;
  for (int f = 0; f < count; ++f) {
    bearings::SyntheticOptions options;
    options.matches = matches;
    options.max_yaw_deg = 3.0;
    options.outlier_ratio = 0.2;
    options.forward_translation = forward;
    frames.push_back(bearings::makeSyntheticFrame(options, 700 + f, f + 1));
  }
  return frames;
}

void writeText(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
}

std::string readError(const std::string& path) {
  try {
    bearings::readBearingFile(path);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(BearingFile, RoundTripKeepsBearingsDtAndTruth) {
  const std::string dir = test::makeTempDir("bearings");
  std::vector<BearingFrame> frames = syntheticFrames(3, 50, 1.0);
  frames[1].has_truth = false;  // a frame without truth stays without
  frames[2].dt = 0.05;
  bearings::writeBearingFile(dir + "/f.txt", frames);
  const std::vector<BearingFrame> back = bearings::readBearingFile(dir + "/f.txt");
  ASSERT_EQ(back.size(), frames.size());
  for (size_t f = 0; f < frames.size(); ++f) {
    EXPECT_EQ(back[f].index, frames[f].index);
    EXPECT_DOUBLE_EQ(back[f].dt, frames[f].dt);
    EXPECT_EQ(back[f].has_truth, frames[f].has_truth);
    if (frames[f].has_truth)
      for (int k = 0; k < 9; ++k) EXPECT_DOUBLE_EQ(back[f].truth[k], frames[f].truth[k]);
    ASSERT_EQ(back[f].prev.size(), frames[f].prev.size());
    for (size_t i = 0; i < frames[f].prev.size(); ++i) {  // %.9g round-trips floats exactly
      EXPECT_EQ(back[f].prev[i].x, frames[f].prev[i].x);
      EXPECT_EQ(back[f].cur[i].z, frames[f].cur[i].z);
    }
  }
}

TEST(BearingFile, ReadsVersionOneAndRejectsBadFilesWithTheLine) {
  const std::string dir = test::makeTempDir("bearings_bad");
  writeText(dir + "/v1.txt", "# visual_gyro bearings v1\nframe 3 1\n0 0 1 0 0 1\n");
  const std::vector<BearingFrame> v1 = bearings::readBearingFile(dir + "/v1.txt");
  ASSERT_EQ(v1.size(), 1u);
  EXPECT_EQ(v1[0].index, 3);
  EXPECT_EQ(v1[0].dt, 0.0);  // unknown: the tools take 10 Hz
  EXPECT_FALSE(v1[0].has_truth);

  const std::string header = "# visual_gyro bearings v2\n";
  const struct {
    const char* name;
    std::string text;
    const char* expected;
  } cases[] = {
      {"header", "# bearings\nframe 1 0 0.1\n", "expected header"},
      {"no_dt", header + "frame 1 1\n0 0 1 0 0 1\n", ":2: expected a positive dt"},
      {"truth", header + "frame 1 1 0.1\ntruth 1 0 0 0 1 0 0 0 2\n0 0 1 0 0 1\n", ":3: truth is not a rotation"},
      {"short_truth", header + "frame 1 1 0.1\ntruth 1 0 0\n0 0 1 0 0 1\n", ":3: expected \"truth\" and 9"},
      {"not_unit", header + "frame 1 1 0.1\n0 0 2 0 0 1\n", ":3: bearing is not a unit vector"},
      {"truncated", header + "frame 1 2 0.1\n0 0 1 0 0 1\n", "1 bearing lines before the frame does"},
  };
  for (const auto& c : cases) {
    writeText(dir + "/" + c.name + ".txt", c.text);
    const std::string error = readError(dir + "/" + c.name + ".txt");
    EXPECT_NE(error.find(c.expected), std::string::npos) << c.name << ": \"" << error << "\"";
  }
  EXPECT_NE(readError(dir + "/absent.txt").find("cannot open"), std::string::npos);
}

// The rule must pass a run against itself and catch a run that is off.
TEST(EstimatorComparison, PassesIdenticalRunsAndCatchesDifferentOnes) {
  const std::vector<BearingFrame> frames = syntheticFrames(6, 600, 1.0);
  EstimatorSettings settings;
  settings.backend = BackendChoice::kCpu;
  const bearings::EstimatorRun a = bearings::runEstimator(createRotationEstimator(settings).get(), frames);
  const bearings::EstimatorRun b = bearings::runEstimator(createRotationEstimator(settings).get(), frames);
  ASSERT_EQ(a.accuracy.frames, 6);
  EXPECT_EQ(a.accuracy.with_truth, 6);
  EXPECT_EQ(a.accuracy.invalid, 0);
  EXPECT_LT(a.accuracy.rot_rmse_deg, 0.1) << "synthetic frames with 20 % outliers: the estimate is accurate";
  const bearings::EstimatorComparison same = bearings::compareEstimatorRuns(a, b);
  EXPECT_TRUE(same.passed());
  EXPECT_EQ(same.max_rotation_difference_deg, 0.0) << "same seed, same backend: identical";

  bearings::EstimatorRun worse = b;  // a GPU run 10 % less accurate
  worse.accuracy.rot_rmse_deg *= 1.1;
  worse.accuracy.rot_rmse_deg += 0.002;
  EXPECT_FALSE(bearings::compareEstimatorRuns(a, worse).passed());
  bearings::EstimatorRun lost = b;  // one estimate invalid on the GPU only
  lost.accuracy.invalid += 1;
  EXPECT_FALSE(bearings::compareEstimatorRuns(a, lost).passed());
  bearings::EstimatorRun shorter = b;
  shorter.accuracy.frames -= 1;
  EXPECT_FALSE(bearings::compareEstimatorRuns(a, shorter).passed());
}

// evaluate's figure `key` for `method` (its JSON line in `text`); NaN when absent.
double jsonNumber(const std::string& text, const std::string& method, const std::string& key) {
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line))
    if (!line.empty() && line[0] == '{' && test::jsonString(line, "method") == method)
      return test::jsonNumber(line, key);
  return std::nan("");
}

// The GPU machine runs the estimator on bearing files exported by evaluate: the figures must be
// evaluate's (the only difference is the file's 9 significant digits per bearing).
TEST(BearingFile, RunFromAnExportedFileReproducesEvaluateFigures) {
  const std::string dir = test::makeTempDir("export");
  int status = 0;
  std::string out = test::runCommand(std::string(VISUAL_GYRO_RENDER) + " --preset drive --frames 12 --out " +
                                         dir + "/drive", &status);
  ASSERT_EQ(status, 0) << out;
  out = test::runCommand(std::string(VISUAL_GYRO_EVALUATE) + " " + dir + "/drive --method vote,paper --backend cpu " +
                             "--quiet --export-bearings " + dir + "/drive.txt", &status);
  ASSERT_EQ(status, 0) << out;
  const std::vector<BearingFrame> frames = bearings::readBearingFile(dir + "/drive.txt");
  ASSERT_EQ(frames.size(), 11u);
  for (const BearingFrame& f : frames) {
    EXPECT_TRUE(f.has_truth);
    EXPECT_NEAR(f.dt, 0.1, 1e-6);
  }
  for (const char* method : {"vote", "paper"}) {
    EstimatorSettings settings;
    settings.backend = BackendChoice::kCpu;
    ASSERT_TRUE(parseMethod(method, &settings.method));
    const bearings::EstimatorRun run = bearings::runEstimator(createRotationEstimator(settings).get(), frames);
    EXPECT_EQ(run.accuracy.invalid, jsonNumber(out, method, "invalid")) << method;
    for (const auto& [key, value] : {std::pair<const char*, double>{"rot_rmse_deg", run.accuracy.rot_rmse_deg},
                                     {"yaw_rmse_deg", run.accuracy.yaw_rmse_deg},
                                     {"mean_rate_dps", run.accuracy.mean_rate_dps}}) {
      const double expected = jsonNumber(out, method, key);
      ASSERT_FALSE(std::isnan(expected)) << method << " " << key << " missing in:\n" << out;
      EXPECT_NEAR(value, expected, 0.01 * std::abs(expected) + 1e-4) << method << " " << key;
    }
  }
}

// The CUDA backend's accuracy goal at the estimator level, on synthetic frames (the shared sequences are
// checked through evaluate in test_accuracy and by cuda_estimator_check on the GPU machine).
TEST(CudaEstimator, GivesTheCpuFiguresOnSyntheticFrames) {
  std::string why;
  if (!cudaBackendUsable(&why)) GTEST_SKIP() << "GPU test skipped: " << why;
  for (const char* method : {"vote", "paper"}) {
    const std::vector<BearingFrame> frames = syntheticFrames(20, 2000, 1.0);
    EstimatorSettings settings;
    ASSERT_TRUE(parseMethod(method, &settings.method));
    settings.backend = BackendChoice::kCpu;
    const bearings::EstimatorRun cpu = bearings::runEstimator(createRotationEstimator(settings).get(), frames);
    settings.backend = BackendChoice::kCuda;
    auto estimator = createRotationEstimator(settings);
    ASSERT_EQ(estimator->backend(), visual_gyro::Backend::kCuda);
    const bearings::EstimatorRun gpu = bearings::runEstimator(estimator.get(), frames);
    const bearings::EstimatorComparison c = bearings::compareEstimatorRuns(cpu, gpu);
    std::string problems;
    for (const std::string& p : c.problems) problems += "[" + p + "] ";
    EXPECT_TRUE(c.passed()) << method << ": " << problems;
    RecordProperty(std::string(method) + "_max_rotation_difference_deg", std::to_string(c.max_rotation_difference_deg));
  }
}

}  // namespace
}  // namespace visual_gyro
