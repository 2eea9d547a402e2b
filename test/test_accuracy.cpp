// End-to-end accuracy: runs the evaluation command (as `make eval` does) on the shared real
// sequences and on rendered ones, and checks the bounds the project promises. The shared-data
// tests skip with the reason when ../shared/data is absent; the rendered ones always run.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "metrics.h"
#include "test_support.h"
#include "visual_gyro/calibration_fit.h"
#include "visual_gyro/rotation_estimator.h"

namespace {

using Figures = std::map<std::string, double>;  // "<method>.<key>" -> value

using visual_gyro::test::jsonNumber;
using visual_gyro::test::jsonString;

// Runs a command, returns its output; fails the test on a non-zero exit.
std::string run(const std::string& command) {
  int status = 0;
  const std::string output = visual_gyro::test::runCommand(command, &status);
  EXPECT_EQ(status, 0) << command << "\n" << output;
  return output;
}

Figures evaluate(const std::string& folder, const std::string& methods, const std::string& extra = "") {
  const std::string output = run(std::string(VISUAL_GYRO_EVALUATE) + " " + folder + " --method " +
                                 methods + " --quiet " + extra);
  Figures figures;
  std::istringstream lines(output);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.empty() || line[0] != '{') continue;
    const std::string method = jsonString(line, "method");
    for (const char* key : {"frames", "invalid", "rot_rmse_deg", "rot_max_deg", "yaw_rmse_deg",
                            "yaw_max_deg", "mean_rate_dps", "nees_mean", "nees_beyond_99", "matches_mean",
                            "gain_jitter", "contrast", "noise", "jpeg", "scale"})
      figures[method + "." + key] = jsonNumber(line, key);
    figures[method + ".backend_is_cuda"] = jsonString(line, "backend") == "cuda" ? 1.0 : 0.0;
    figures[method + ".truth_is_poses"] = jsonString(line, "truth") == "poses" ? 1.0 : 0.0;
  }
  EXPECT_FALSE(figures.empty()) << "no JSON line from evaluate:\n" << output;
  return figures;
}

std::string sharedOrSkip(const std::string& name, std::string* why) {
  return visual_gyro::test::sharedSequence(name, why);
}

/// Runs `body(name, folder)` for each of `names` present under the data folder, printing why each
/// missing one is skipped; returns how many ran.
template <typename Body>
int forEachSharedSequence(std::initializer_list<const char*> names, Body body) {
  int ran = 0;
  for (const char* name : names) {
    std::string missing;
    const std::string folder = sharedOrSkip(name, &missing);
    if (folder.empty()) {
      std::cout << "[ SKIPPED  ] " << name << ": " << missing << "\n";
      continue;
    }
    body(name, folder);
    ++ran;
  }
  return ran;
}

/// evaluate's per-frame CSV as rows of named cells (the header's names).
std::vector<std::map<std::string, std::string>> readFrameRows(const std::string& csv) {
  std::ifstream in(csv);
  std::string line;
  std::vector<std::string> header;
  if (std::getline(in, line)) {
    std::istringstream cells(line);
    for (std::string cell; std::getline(cells, cell, ',');) header.push_back(cell);
  }
  std::vector<std::map<std::string, std::string>> rows;
  while (std::getline(in, line)) {
    std::istringstream cells(line);
    std::map<std::string, std::string> row;
    size_t c = 0;
    for (std::string cell; std::getline(cells, cell, ',') && c < header.size(); ++c) row[header[c]] = cell;
    rows.push_back(row);
  }
  EXPECT_FALSE(rows.empty()) << "no per-frame rows in " << csv;
  return rows;
}

void record(const Figures& f) {
  for (const auto& [key, value] : f) ::testing::Test::RecordProperty(key, std::to_string(value));
}

// The covariance is honest when the normalised estimation error squared of the rotation averages
// about 3 (three degrees of freedom) and few frames fall beyond the 99 % chi-square bound. The
// evaluation adds the truth's own error to the covariance it judges.
void expectHonestCovariance(const Figures& f, const std::string& method) {
  EXPECT_GE(f.at(method + ".nees_mean"), 1.0) << method << ": covariance too pessimistic";
  EXPECT_LE(f.at(method + ".nees_mean"), visual_gyro::metrics::kHonestNeesMeanMax) << method << ": covariance too optimistic";
  EXPECT_LE(f.at(method + ".nees_beyond_99"), visual_gyro::metrics::kHonestBeyond99Max)
      << method << ": too many frames beyond the 99 % bound";
}

// Integer positions' covariance model is cautious by design: it covers the blur-induced shifts of
// integer corners, which neither residuals nor their spread show, also where there is no blur. It
// is never over-confident and at most about three times too wide in standard deviation.
void expectCautiousCovariance(const Figures& f, const std::string& method) {
  EXPECT_GE(f.at(method + ".nees_mean"), 0.3) << method << ": covariance far too pessimistic";
  EXPECT_LE(f.at(method + ".nees_mean"), visual_gyro::metrics::kHonestNeesMeanMax) << method << ": covariance too optimistic";
  EXPECT_LE(f.at(method + ".nees_beyond_99"), visual_gyro::metrics::kHonestBeyond99Max)
      << method << ": too many frames beyond the 99 % bound";
}

// The accuracy goals of the shared sequences at their own rate (doc/evaluation.md): rotation error
// RMSE [deg], and the worst frame of the shaken drone (the covariance's honesty on them is
// SharedSequences.SubpixelCovarianceIsHonest's).
constexpr double kKittiTurnRmseGoalDeg = 0.045;
constexpr double kKittiStraightRmseGoalDeg = 0.065;
constexpr double kEurocShakeRmseGoalDeg = 0.030;
constexpr double kEurocShakeMaxGoalDeg = 0.2;

/// The native front end with integer FAST positions and no tracking (the defaults' cheaper
/// alternative). The defaults are sub-pixel positions with tracking.
const char* const kIntegerFrontEnd = "--set subpixel_refinement=false --set track_unmatched=false";
/// Sub-pixel positions without tracking.
const char* const kSubpixelOnlyFrontEnd = "--set subpixel_refinement=true --set track_unmatched=false";

}  // namespace

TEST(KittiTurn, PaperYawWithinBoundAndVoteBeatsFivePoint) {
  std::string why;
  const std::string folder = sharedOrSkip("kitti_turn", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  const Figures f = evaluate(folder, "paper,vote,essential5");
  record(f);
  EXPECT_EQ(f.at("paper.frames"), 50);
  EXPECT_LE(f.at("paper.yaw_rmse_deg"), 0.4);
  EXPECT_EQ(f.at("vote.invalid"), 0);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.8 * f.at("essential5.rot_rmse_deg"));
  EXPECT_LE(f.at("vote.rot_max_deg"), 0.5);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), kKittiTurnRmseGoalDeg);
}

TEST(KittiStraight, VoteBeatsFivePointUnderForwardMotion) {
  std::string why;
  const std::string folder = sharedOrSkip("kitti_straight", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  const Figures f = evaluate(folder, "vote,essential5");
  record(f);
  EXPECT_EQ(f.at("vote.frames"), 50);
  EXPECT_EQ(f.at("vote.invalid"), 0);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.8 * f.at("essential5.rot_rmse_deg"));
  EXPECT_LE(f.at("vote.rot_max_deg"), 0.5);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), kKittiStraightRmseGoalDeg);
}

// A drone shaken by hand 1-2 m from a pallet: fast rotation, parallax, blur. The truth is the
// ground-truth poses (no gyro bias). No streak of wrong estimates: vote beats the 5-point RANSAC
// on the same matches and its worst frame stays within half a degree.
TEST(EurocShake, VoteBeatsFivePointWithoutLockIn) {
  std::string why;
  const std::string folder = sharedOrSkip("euroc_mh01_shake", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  const Figures f = evaluate(folder, "vote,essential5");
  record(f);
  EXPECT_EQ(f.at("vote.truth_is_poses"), 1.0);
  EXPECT_EQ(f.at("vote.frames"), 99);
  EXPECT_EQ(f.at("vote.invalid"), 0);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.8 * f.at("essential5.rot_rmse_deg"));
  EXPECT_LE(f.at("vote.rot_rmse_deg"), kEurocShakeRmseGoalDeg);
  EXPECT_LE(f.at("vote.rot_max_deg"), kEurocShakeMaxGoalDeg);
}

// Half the matches wrong, near structure, at half the camera's rate (2-5 deg per pair). The winner
// of one frame sat 2.1 deg from the truth, in another basin with another translation, where the
// truth with a fitted translation explained 669 matches against its 545: the restarts from the
// winner's rotation could not reach it, those from the contenders' rotations do (RMSE 0.32 ->
// 0.12 deg, worst frame 2.07 -> 0.67 deg). Another frame's right motion had a translation 35 deg
// from every restart direction until the corners joined them: one seed of three lost it (invalid,
// RMSE 0.84 deg). Three estimator seeds are judged: each honest, without an invalid frame, and
// accurate.
TEST(EurocShake, HalfTheMatchesWrongAtHalfTheRateFindsTheRightBasin) {
  std::string why;
  const std::string folder = sharedOrSkip("euroc_mh01_shake", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  for (const int seed : {1, 2, 3}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Figures f = evaluate(folder, "vote", "--backend cpu --stride 2 --outliers 0.5 --seed " + std::to_string(seed));
    std::printf("seed %d: RMSE %.3f deg, worst %.3f deg, invalid %.0f, NEES %.2f, %.0f %% beyond\n", seed,
                f.at("vote.rot_rmse_deg"), f.at("vote.rot_max_deg"), f.at("vote.invalid"), f.at("vote.nees_mean"),
                100.0 * f.at("vote.nees_beyond_99"));
    EXPECT_EQ(f.at("vote.invalid"), 0);
    expectHonestCovariance(f, "vote");
    EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.2);
  }
}

// Pairs five frames apart near structure (about 5 deg and 10 cm a pair): along the
// rotation/translation valley the jackknives spread much further than the statistical covariance,
// further than its mean scale covers. With the scale alone 7 of the 57 pairs of seeds 1-3 lay
// beyond the 99 % bound (NEES means 3.6-5.3); covering the jackknives' spread in every direction
// leaves 1. The share is judged over the three seeds together (one pair of 19 is already 5 %).
TEST(EurocShake, PairsFiveFramesApartStayHonest) {
  std::string why;
  const std::string folder = sharedOrSkip("euroc_mh01_shake", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  double beyond = 0.0, valid = 0.0, nees = 0.0, rmse = 0.0;
  const std::vector<int> seeds{1, 2, 3};
  for (const int seed : seeds) {
    const Figures f = evaluate(folder, "vote", "--backend cpu --stride 5 --seed " + std::to_string(seed));
    std::printf("seed %d: RMSE %.3f deg, worst %.3f deg, NEES %.2f, %.0f %% beyond\n", seed, f.at("vote.rot_rmse_deg"),
                f.at("vote.rot_max_deg"), f.at("vote.nees_mean"), 100.0 * f.at("vote.nees_beyond_99"));
    EXPECT_EQ(f.at("vote.invalid"), 0) << "seed " << seed;
    const double frames = f.at("vote.frames") - f.at("vote.invalid");
    beyond += f.at("vote.nees_beyond_99") * frames;
    valid += frames;
    nees += f.at("vote.nees_mean") / seeds.size();
    rmse += f.at("vote.rot_rmse_deg") / seeds.size();
  }
  ASSERT_GT(valid, 0.0);
  EXPECT_LE(beyond / valid, visual_gyro::metrics::kHonestBeyond99Max) << "too many pairs beyond the 99 % bound";
  EXPECT_GE(nees, 1.0) << "covariance too pessimistic";
  EXPECT_LE(nees, visual_gyro::metrics::kHonestNeesMeanMax) << "covariance too optimistic";
  EXPECT_LE(rmse, 0.6);
}

// The shaken drone's footage made dimmer (a third of its contrast), noisier and JPEG-compressed as
// it is read: fewer matches, still accurate and honest.
TEST(EurocShake, DimmedNoisyJpegFootageStaysAccurateAndHonest) {
  std::string why;
  const std::string folder = sharedOrSkip("euroc_mh01_shake", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  const Figures f = evaluate(folder, "vote", "--backend cpu --contrast 0.3 --noise 2 --jpeg 40");
  // The images were degraded (the run says so, and finds fewer matches than the 1 190 of the
  // footage as recorded).
  EXPECT_DOUBLE_EQ(f.at("vote.contrast"), 0.3);
  EXPECT_DOUBLE_EQ(f.at("vote.noise"), 2.0);
  EXPECT_DOUBLE_EQ(f.at("vote.jpeg"), 40.0);
  EXPECT_LT(f.at("vote.matches_mean"), 1100.0);
  EXPECT_EQ(f.at("vote.invalid"), 0);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.1);
  EXPECT_LE(f.at("vote.rot_max_deg"), 0.5);
  expectHonestCovariance(f, "vote");
}

// An automatic exposure stepping between frames (every image's grey levels times a factor drawn
// in [0.75, 1.25], saturating at white): FAST and BRIEF compare grey levels within one image, and
// the sub-pixel alignment removes a brightness offset, so the estimate stays within the goal
// (0.026 against 0.024 deg, 1 139 matches a pair against 1 190) and honest.
TEST(EurocShake, ExposureSteppingBetweenFramesStaysAccurateAndHonest) {
  std::string why;
  const std::string folder = sharedOrSkip("euroc_mh01_shake", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  const Figures f = evaluate(folder, "vote", "--backend cpu --gain-jitter 0.25");
  EXPECT_DOUBLE_EQ(f.at("vote.gain_jitter"), 0.25);
  EXPECT_LT(f.at("vote.matches_mean"), 1170.0);  // the images were stepped: fewer corners pass FAST
  EXPECT_EQ(f.at("vote.invalid"), 0);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.030);
  EXPECT_LE(f.at("vote.rot_max_deg"), 0.2);
  expectHonestCovariance(f, "vote");
}

// At a twelfth of its contrast with noise 3 and JPEG 75 only about half the matches are inliers and
// many more lie just outside the gate; the jackknife on fixed inliers then left the covariance too
// tight (NEES 5.60, 13 % of frames beyond the 99 % bound), the refits without each group cover it.
TEST(EurocShake, VeryDimFootageNearStructureStaysHonest) {
  std::string why;
  const std::string folder = sharedOrSkip("euroc_mh01_shake", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  const Figures f = evaluate(folder, "vote", "--backend cpu --contrast 0.08 --noise 3 --jpeg 75");
  EXPECT_DOUBLE_EQ(f.at("vote.contrast"), 0.08);
  EXPECT_EQ(f.at("vote.invalid"), 0);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.5);
  expectHonestCovariance(f, "vote");
}

// With sub-pixel positions and tracking (the defaults) the covariance counts the independent
// matches the spatial jackknife finds and a smaller floor: honest on all three sequences with pose
// truth.
TEST(SharedSequences, SubpixelCovarianceIsHonest) {
  const auto each = [&](const char* name, const std::string& folder) {
    const Figures f = evaluate(folder, "vote");
    record(f);
    std::printf("%s: sub-pixel positions and tracking, NEES mean %.2f, %.0f %% beyond the 99 %% bound\n", name,
                f.at("vote.nees_mean"), 100.0 * f.at("vote.nees_beyond_99"));
    EXPECT_EQ(f.at("vote.invalid"), 0) << name;
    SCOPED_TRACE(name);
    expectHonestCovariance(f, "vote");
  };
  const int judged = forEachSharedSequence({"kitti_turn", "kitti_straight", "euroc_mh01_shake"}, each);
  if (judged == 0) GTEST_SKIP() << "no shared sequence with pose truth present under the data folder";
}

// With integer positions the covariance keeps its fixed model (40 independent matches, a larger
// floor): never over-confident on the three sequences with pose truth.
TEST(SharedSequences, IntegerCovarianceIsCautious) {
  const auto each = [&](const char* name, const std::string& folder) {
    const Figures f = evaluate(folder, "vote", kIntegerFrontEnd);
    std::printf("%s: integer positions, NEES mean %.2f, %.0f %% beyond the 99 %% bound\n", name,
                f.at("vote.nees_mean"), 100.0 * f.at("vote.nees_beyond_99"));
    SCOPED_TRACE(name);
    expectCautiousCovariance(f, "vote");
  };
  const int judged = forEachSharedSequence({"kitti_turn", "kitti_straight", "euroc_mh01_shake"}, each);
  if (judged == 0) GTEST_SKIP() << "no shared sequence with pose truth present under the data folder";
}

/// vote's per-frame rotation error vector [deg] (camera axes x, y, z) against the truth, by frame,
/// read from evaluate's per-frame CSV; frames without a complete error vector are left out.
std::map<int, std::array<double, 3>> frameErrors(const std::string& folder, const std::string& extra) {
  const std::string csv = visual_gyro::test::makeTempDir("frames") + "/frames.csv";
  run(std::string(VISUAL_GYRO_EVALUATE) + " " + folder + " --method vote --quiet --csv " + csv + " " + extra);
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  {
    std::istringstream cells(line);
    for (std::string cell; std::getline(cells, cell, ',');) header.push_back(cell);
  }
  const std::vector<std::string> axes{"err_x_deg", "err_y_deg", "err_z_deg"};
  std::map<int, std::array<double, 3>> errors;
  while (std::getline(in, line)) {
    std::istringstream cells(line);
    std::vector<std::string> row;
    for (std::string cell; std::getline(cells, cell, ',');) row.push_back(cell);
    std::array<double, 3> e{};
    int found = 0, frame = -1;
    for (size_t c = 0; c < header.size() && c < row.size(); ++c) {
      if (header[c] == "frame") frame = std::stoi(row[c]);
      for (size_t a = 0; a < axes.size(); ++a)
        if (header[c] == axes[a] && !row[c].empty()) {
          e[a] = std::stod(row[c]);
          ++found;
        }
    }
    if (frame >= 0 && found == 3) errors[frame] = e;
  }
  EXPECT_FALSE(errors.empty()) << "no per-frame errors in " << csv;
  return errors;
}

/// Per axis, the RMS over the frames both runs scored of a[frame] - b[frame] (b empty: of a alone).
std::vector<double> rmsPerAxis(const std::map<int, std::array<double, 3>>& a,
                               const std::map<int, std::array<double, 3>>& b = {}) {
  std::vector<double> square(3, 0.0);
  int frames = 0;
  for (const auto& [frame, e] : a) {
    std::array<double, 3> other{};
    if (!b.empty()) {
      const auto it = b.find(frame);
      if (it == b.end()) continue;
      other = it->second;
    }
    for (int k = 0; k < 3; ++k) square[k] += (e[k] - other[k]) * (e[k] - other[k]);
    ++frames;
  }
  for (double& v : square) v = frames > 0 ? std::sqrt(v / frames) : NAN;
  return square;
}

/// Per axis, the spread (standard deviation over the frames) of vote's per-frame rotation error
/// against the gyro [deg]. The gyro's bias is constant over the few seconds, so it moves the mean
/// error but not its spread (evaluate removes it anyway).
std::vector<double> errorSpreadAgainstGyro(const std::string& folder, const std::string& extra) {
  const std::map<int, std::array<double, 3>> errors = frameErrors(folder, extra);
  EXPECT_GT(errors.size(), 80u) << "too few per-frame errors on " << folder;
  std::array<double, 3> mean{};
  for (const auto& [frame, e] : errors)
    for (int k = 0; k < 3; ++k) mean[k] += e[k] / errors.size();
  std::map<int, std::array<double, 3>> centred;
  for (const auto& [frame, e] : errors) centred[frame] = {e[0] - mean[0], e[1] - mean[1], e[2] - mean[2]};
  return rmsPerAxis(centred);
}

// Why the covariance floor is as large as it is. On KITTI the per-frame rotation error against the
// ground-truth poses is common to every front end: vote on sub-pixel positions with tracking (the
// defaults), on integer positions and on KLT tracks (which share no
// corner with the native front end) differ from one another by a fraction of their error against
// the truth, frame by frame. That common part (0.02-0.04 deg per axis, 0.14 deg on the worst
// frames) is not in the matches, so no residual can show it; it is the truth's own error (or the
// frame timing's), which the evaluation adds to the covariance it judges (per axis: KITTI's
// specified heading and tilt accuracy).
TEST(KittiStraight, ErrorAgainstTheTruthIsCommonToEveryFrontEnd) {
  std::string why;
  const std::string folder = sharedOrSkip("kitti_straight", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  const auto subpixel = frameErrors(folder, "");
  const auto integer = frameErrors(folder, kIntegerFrontEnd);
  const auto klt = frameErrors(folder, "--front-end klt");
  const std::vector<double> truth = rmsPerAxis(subpixel), to_integer = rmsPerAxis(subpixel, integer),
                            to_klt = rmsPerAxis(subpixel, klt);
  for (int a = 0; a < 3; ++a) {
    std::printf("axis %d: sub-pixel vote %.4f deg RMS from the truth, %.4f deg from integer positions, "
                "%.4f deg from KLT tracks\n",
                a, truth[a], to_integer[a], to_klt[a]);
    EXPECT_LE(to_integer[a], 0.4 * truth[a]) << "axis " << a;
    EXPECT_LE(to_klt[a], 0.4 * truth[a]) << "axis " << a;
  }
}

TEST(EurocStatic, NoFalseRotationWhenStandingStill) {
  std::string why;
  const std::string folder = sharedOrSkip("euroc_v101_static", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  // Integer positions round the camera's small vibration (below) away: no rotation at all.
  const Figures f = evaluate(folder, "vote", kIntegerFrontEnd);
  record(f);
  EXPECT_EQ(f.at("vote.frames"), 94);
  EXPECT_LE(f.at("vote.mean_rate_dps"), 0.3);
}

// The drone stands on the ground, but the camera is not perfectly still: the gyro sees a
// vibration of about 0.5 deg/s (0.02 deg per frame) once the frames start. Integer positions
// round it to zero rotation; sub-pixel match positions resolve it: the estimate follows the gyro
// frame by frame, apart from the gyro's constant bias, to a hundredth of a degree per axis, and
// its mean rate is the vibration's size, not a false rotation.
TEST(EurocStatic, SubpixelPositionsFollowTheVibrationTheGyroSees) {
  std::string why;
  const std::string folder = sharedOrSkip("euroc_v101_static", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  const Figures f = evaluate(folder, "vote");
  EXPECT_EQ(f.at("vote.frames"), 94);
  EXPECT_LE(f.at("vote.mean_rate_dps"), 0.6);
  const std::vector<double> spread = errorSpreadAgainstGyro(folder, "");
  const std::vector<double> integer = errorSpreadAgainstGyro(folder, kIntegerFrontEnd);
  for (size_t a = 0; a < spread.size(); ++a) {
    std::printf("axis %zu: error spread against the gyro %.4f deg (integer positions: %.4f deg)\n", a,
                spread[a], integer[a]);
    EXPECT_LE(spread[a], 0.01) << "axis " << a;
    EXPECT_LT(spread[a], integer[a]) << "axis " << a;
  }
}

// The CUDA backend's goal: it gives the CPU backend's figures (within 5 %) on every shared
// sequence. Both runs use the same matches and seeds; they differ only by float rounding in the
// hypotheses (see cuda/README.md), so the refined estimates agree far closer than 5 %.
TEST(SharedSequences, CudaBackendGivesTheCpuFigures) {
  std::string why;
  if (!visual_gyro::cudaBackendUsable(&why)) GTEST_SKIP() << "GPU test skipped: " << why;
  const auto each = [&](const char* name, const std::string& folder) {
    const Figures cpu = evaluate(folder, "paper,vote", "--backend cpu");
    const Figures gpu = evaluate(folder, "paper,vote", "--backend cuda");
    record(gpu);
    for (const char* method : {"paper", "vote"}) {
      const std::string m = method;
      EXPECT_EQ(gpu.at(m + ".backend_is_cuda"), 1.0) << name << " " << m << ": the CUDA run fell back to the CPU";
      EXPECT_EQ(gpu.at(m + ".frames"), cpu.at(m + ".frames")) << name << " " << m;
      EXPECT_EQ(gpu.at(m + ".invalid"), cpu.at(m + ".invalid")) << name << " " << m;
      // 5 % of the CPU figure, plus 1e-3 (deg or deg/s) so that figures near zero are not held
      // to an impossible relative bound.
      for (const char* key : {"rot_rmse_deg", "yaw_rmse_deg", "rot_max_deg", "mean_rate_dps"}) {
        const double c = cpu.at(m + "." + key), g = gpu.at(m + "." + key);
        if (std::isnan(c) && std::isnan(g)) continue;  // e.g. no rotation truth on EuRoC
        EXPECT_NEAR(g, c, 0.05 * std::abs(c) + 1e-3) << name << " " << m << " " << key;
      }
    }
  };
  const int compared = forEachSharedSequence({"kitti_turn", "kitti_straight", "euroc_v101_static"}, each);
  if (compared == 0) GTEST_SKIP() << "no shared sequence present under the data folder";
}

class Rendered : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = visual_gyro::test::makeTempDir("accuracy");
    for (const char* preset : {"drive", "handheld", "forward"})
      run(std::string(VISUAL_GYRO_RENDER) + " --preset " + preset + " --frames 25 --out " + root_ +
          "/" + preset);
    // The hand-held room with the hand moving the camera by +-5 cm, as a phone carried by hand.
    run(std::string(VISUAL_GYRO_RENDER) + " --preset handheld --hand-translation-cm 5 --frames 25 --out " + root_ +
        "/handheld_5cm");
    // Forty frames, as `make bench` renders: around frame 30 the drone's translation reverses, and
    // those pairs are the hardest of the rotation/translation valley.
    run(std::string(VISUAL_GYRO_RENDER) + " --preset drone_near --frames 40 --out " + root_ + "/drone_near");
    // The hand-held room through a phone-like rolling shutter (28 ms read-out at 30 Hz), long enough
    // for the estimator to judge the shutter over its window of frames.
    run(std::string(VISUAL_GYRO_RENDER) + " --preset handheld_rs --frames 61 --out " + root_ + "/handheld_rs");
  }
  static std::string root_;
};
std::string Rendered::root_;

TEST_F(Rendered, DriveSequenceVoteBeatsFivePoint) {
  const Figures f = evaluate(root_ + "/drive", "vote,essential5");
  record(f);
  EXPECT_EQ(f.at("vote.frames"), 24);
  EXPECT_EQ(f.at("vote.invalid"), 0);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.8 * f.at("essential5.rot_rmse_deg"));
  EXPECT_LE(f.at("vote.rot_max_deg"), 0.5);
}

TEST_F(Rendered, DriveSequenceWithHalfTheMatchesWrong) {
  const Figures f = evaluate(root_ + "/drive", "vote,essential5", "--outliers 0.5");
  record(f);
  EXPECT_EQ(f.at("vote.invalid"), 0);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.8 * f.at("essential5.rot_rmse_deg"));
  EXPECT_LE(f.at("vote.rot_max_deg"), 0.5);
}

TEST_F(Rendered, ForwardDrivingVoteBeatsFivePoint) {
  const Figures f = evaluate(root_ + "/forward", "vote,essential5");
  record(f);
  EXPECT_EQ(f.at("vote.invalid"), 0);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.8 * f.at("essential5.rot_rmse_deg"));
  EXPECT_LE(f.at("vote.rot_max_deg"), 0.5);
}

// The rendered counterpart of the shaken drone: everything 1-2 m away, 2-5 cm and up to ~3 deg
// per frame, so rotation and lateral translation are nearly ambiguous. Where the translation
// reverses (about a centimetre per frame) every candidate of a frame once converged 0.1-0.4 deg
// along the valley from the truth, with a covariance a tenth of that: the valley's steps and the
// choice between refinements counted inliers, and along the valley the wrong rotation and the
// right one keep nearly every match; the truncated cost tells them apart.
TEST_F(Rendered, NearStructureVoteBeatsFivePoint) {
  const Figures f = evaluate(root_ + "/drone_near", "vote,essential5");
  record(f);
  EXPECT_EQ(f.at("vote.frames"), 39);
  EXPECT_EQ(f.at("vote.invalid"), 0);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.8 * f.at("essential5.rot_rmse_deg"));
  EXPECT_LE(f.at("vote.rot_max_deg"), 0.1);
  EXPECT_LE(f.at("vote.nees_mean"), 6.0);
  EXPECT_EQ(f.at("vote.nees_beyond_99"), 0.0) << "a confident wrong frame";
}

// The same pairs with other random triples. Which candidates a frame gets depends on the draw;
// the valley search must then find the right basin from whichever wrong one it starts in. Seed 2
// once started frame 30 in a basin 0.4 deg off with a covariance of 0.05 deg: its valley steps were
// costed at sampled translations, against the winner at its refined one, so none looked better.
// Seed 6 once took a forward-moving winner at frame 30, 0.35 deg off under NEES 104: its
// translation's standard deviation (0.47 deg) lay under the restarts' bound of then (0.5 deg), and
// no search reached the lateral motion of the frames before it.
TEST_F(Rendered, NearStructureHoldsForEveryDraw) {
  for (const int seed : {2, 3, 4, 5, 6}) {
    const Figures f = evaluate(root_ + "/drone_near", "vote", "--backend cpu --seed " + std::to_string(seed));
    EXPECT_EQ(f.at("vote.invalid"), 0) << "seed " << seed;
    EXPECT_LE(f.at("vote.rot_max_deg"), 0.1) << "seed " << seed;
    EXPECT_EQ(f.at("vote.nees_beyond_99"), 0.0) << "a confident wrong frame with seed " << seed;
  }
}

// The same motion over other textures (renderer seeds): other matches, other basins. Before the
// previous frame's motion started a refinement of its own, every voted candidate of one frame of
// each of these started from a translation its verification sampled (forward where the truth is
// sideways) and converged to a wrong basin 0.3-1.1 deg off, with a covariance of a few hundredths
// of a degree: six of sixteen textures had such a frame, these three among them.
TEST_F(Rendered, NearStructureHoldsForOtherTextures) {
  for (const int texture : {4, 12, 16}) {
    const std::string folder = root_ + "/drone_near_texture" + std::to_string(texture);
    run(std::string(VISUAL_GYRO_RENDER) + " --preset drone_near --frames 40 --seed " + std::to_string(texture) +
        " --out " + folder);
    const Figures f = evaluate(folder, "vote", "--backend cpu");
    EXPECT_EQ(f.at("vote.invalid"), 0) << "texture " << texture;
    EXPECT_LE(f.at("vote.rot_max_deg"), 0.1) << "texture " << texture;
    EXPECT_EQ(f.at("vote.nees_beyond_99"), 0.0) << "a confident wrong frame with texture " << texture;
  }
}

// The camera at a quarter of its rate: about 10 deg and 10-15 cm per pair, priors degrees off. With
// these draws every candidate of one frame once converged to a forward translation with a rotation
// 1.5-4.3 deg off that explained about 60 % of the matches, under a covariance of a few hundredths
// of a degree; the previous pair's translation direction was no help, 90 deg from this one's.
TEST_F(Rendered, NearStructureHoldsAtAQuarterOfTheRate) {
  for (const int seed : {3, 4, 5}) {
    const Figures f =
        evaluate(root_ + "/drone_near", "vote", "--backend cpu --stride 4 --seed " + std::to_string(seed));
    EXPECT_EQ(f.at("vote.invalid"), 0) << "seed " << seed;
    EXPECT_LE(f.at("vote.rot_max_deg"), 0.1) << "seed " << seed;
    EXPECT_EQ(f.at("vote.nees_beyond_99"), 0.0) << "a confident wrong frame with seed " << seed;
  }
}

TEST_F(Rendered, HandheldRotationBothMethods) {
  const Figures f = evaluate(root_ + "/handheld", "paper,vote");
  record(f);
  EXPECT_EQ(f.at("vote.invalid"), 0);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.1);
  EXPECT_LE(f.at("paper.yaw_rmse_deg"), 0.4);
}

// A hand moving the camera by centimetres in a room leaves a few per cent of the matches to a pure
// rotation, under the model choice's margin, and its translation explains nearly all of them: the
// share test takes the general motion there (0.073 deg a pair as pure rotations).
TEST_F(Rendered, HandheldMovedByCentimetresTakesTheTranslation) {
  const Figures f = evaluate(root_ + "/handheld_5cm", "vote,essential5,fundamental8");
  record(f);
  EXPECT_EQ(f.at("vote.invalid"), 0);
  EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.04);
  const double best_other = std::min(f.at("essential5.rot_rmse_deg"), f.at("fundamental8.rot_rmse_deg"));
  EXPECT_LE(f.at("vote.rot_rmse_deg"), 0.5 * best_other);
  EXPECT_LE(f.at("vote.nees_beyond_99"), 0.05);
}

// Through a rolling shutter the rotation changes down the image; the row skew's model takes it in
// once the estimator's window of frames has judged the shutter: compared on the pairs after the
// window, against the same estimator without it and against OpenGV's rotation-only RANSAC where the
// build has OpenGV (the goal on hand-held rolling-shutter footage).
TEST_F(Rendered, HandheldRollingShutterTakesTheRowSkew) {
  const bool opengv = run(std::string(VISUAL_GYRO_EVALUATE) + " --list-methods").find("opengv_rotation_only") !=
                      std::string::npos;
  const std::string csv = root_ + "/handheld_rs.csv";
  const Figures f = evaluate(root_ + "/handheld_rs",
                             std::string("vote,vote-without-row_skew") + (opengv ? ",opengv_rotation_only" : ""),
                             "--csv " + csv);
  record(f);
  EXPECT_EQ(f.at("vote.invalid"), 0);
  EXPECT_LE(f.at("vote.nees_beyond_99"), 0.05);
  std::map<std::string, std::pair<double, int>> late;  // method -> sum of squared errors, pairs
  int skewed = 0;
  for (const auto& row : readFrameRows(csv)) {
    if (std::stoi(row.at("frame")) < static_cast<int>(visual_gyro::kFitWindowFrames)) continue;
    auto& [sum, count] = late[row.at("method")];
    sum += std::pow(std::stod(row.at("rot_err_deg")), 2);
    ++count;
    skewed += row.at("method") == "vote" && !row.at("row_skew_deg").empty() && std::stod(row.at("row_skew_deg")) > 0.0;
  }
  const auto rmse = [&](const std::string& m) { return std::sqrt(late[m].first / std::max(1, late[m].second)); };
  std::printf("rolling shutter, pairs after the window: vote %.4f deg (%d with a skew), without it %.4f deg\n",
              rmse("vote"), skewed, rmse("vote-without-row_skew"));
  EXPECT_GE(skewed, late["vote"].second / 2);
  EXPECT_LE(rmse("vote"), 0.9 * rmse("vote-without-row_skew"));
  if (opengv) EXPECT_LE(rmse("vote"), rmse("opengv_rotation_only"));
  else std::printf("this build has no OpenGV: vote compared with itself without the row skew only\n");
}

// `make bench`'s timing series come from `evaluate --timing-sweep`: both series, baselines once on
// the hypotheses axis, topped-up pairs flagged, and vote's time split into voter and host parts.
TEST_F(Rendered, TimingSweepWritesBothSeriesWithTheSplit) {
  const std::string csv = root_ + "/sweep.csv";
  run(std::string(VISUAL_GYRO_EVALUATE) + " " + root_ + "/drive --method vote,essential5 --backend cpu --quiet " +
      "--frames 2 --sweep-hypotheses 100,1000 --sweep-matches 250,4000 --sweep-repeats 1 --timing-sweep " + csv);
  std::ifstream in(csv);
  std::string header;
  ASSERT_TRUE(std::getline(in, header)) << "no CSV at " << csv;
  EXPECT_EQ(header,
            "source,dataset,series,method,backend,hypotheses,matches,pairs,real_fraction,ms_mean,ms_median,ms_min,"
            "vote_ms_mean,vote_device_ms_mean,refine_ms_mean");
  std::map<std::string, int> rows;  // "<series>/<method>" -> count
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream cells(line);
    for (std::string cell; std::getline(cells, cell, ',');) f.push_back(cell);
    if (line.back() == ',') f.push_back("");
    ASSERT_EQ(f.size(), 15u) << line;
    const std::string series = f[2], method = f[3];
    const int hypotheses = std::stoi(f[5]), matches = std::stoi(f[6]);
    const double real = std::stod(f[8]), ms = std::stod(f[9]);
    ++rows[series + "/" + method];
    EXPECT_EQ(f[4], "cpu") << line;
    EXPECT_EQ(std::stoi(f[7]), 2) << line;
    EXPECT_GT(ms, 0.0) << line;
    EXPECT_EQ(hypotheses == 0, method == "essential5") << line;  // baselines have no hypothesis count
    if (series == "hypotheses") EXPECT_EQ(matches, 2000) << line;
    if (series == "matches" && method == "vote") EXPECT_EQ(hypotheses, 10000) << line;
    // The rendered drive has about 1 000 matches a pair: 250 is a real subset, 4 000 is topped up.
    if (matches == 250) EXPECT_EQ(real, 1.0) << line;
    if (matches == 4000) EXPECT_LT(real, 0.5) << line;
    if (method == "vote") {
      const double vote = std::stod(f[12]), refine = std::stod(f[14]);
      EXPECT_TRUE(f[13].empty()) << "no GPU kernels on the CPU: " << line;
      EXPECT_GT(vote, 0.0) << line;
      EXPECT_GE(refine, 0.0) << line;
      EXPECT_LE(vote + refine, ms * 1.001 + 1e-3) << line;
    } else {
      EXPECT_TRUE(f[12].empty() && f[14].empty()) << line;
    }
  }
  EXPECT_EQ(rows["hypotheses/vote"], 2);
  EXPECT_EQ(rows["hypotheses/essential5"], 1);
  EXPECT_EQ(rows["matches/vote"], 2);
  EXPECT_EQ(rows["matches/essential5"], 2);
}

// ---------------------------------------------------------------------------------------------
// Front end for hard footage: guided matching and the adaptive threshold keep vote's accuracy on
// the shared sequences, the native front end is at least as accurate as ORB and KLT there, and
// the rendered dim room with motion blur and JPEG gets enough matches for an accurate estimate.
// (The time goals are measured by `make bench`, not here.)
// ---------------------------------------------------------------------------------------------

namespace {

/// vote's figures (rot_rmse_deg, rot_max_deg, mean_rate_dps, invalid, matches_mean) on `folder`.
Figures evaluateVote(const std::string& folder, const std::string& extra) {
  const std::string output =
      run(std::string(VISUAL_GYRO_EVALUATE) + " " + folder + " --method vote --backend cpu --quiet " + extra);
  Figures figures;
  std::istringstream lines(output);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.empty() || line[0] != '{') continue;
    for (const char* key : {"frames", "invalid", "rot_rmse_deg", "rot_max_deg", "mean_rate_dps", "matches_mean",
                            "fallback_pairs", "guided_pairs"})
      figures[key] = jsonNumber(line, key);
  }
  EXPECT_FALSE(figures.empty()) << "no JSON line from evaluate:\n" << output;
  return figures;
}

/// The front end as it was before adaptive detection, guided matching, sub-pixel positions and
/// tracking.
const char* const kFixedGlobalFrontEnd =
    "--set matching=global --set min_fast_threshold=20 --set subpixel_refinement=false --set track_unmatched=false";

}  // namespace

TEST(SharedSequences, GuidedAdaptiveFrontEndKeepsVoteAccuracy) {
  const auto each = [&](const char* name, const std::string& folder) {
    const Figures now = evaluateVote(folder, "");
    const Figures before = evaluateVote(folder, kFixedGlobalFrontEnd);
    std::printf("%s: vote rotation RMSE %.4f deg with %.0f matches (guided %0.f pairs, %.0f fell back), %.4f deg with "
                "%.0f matches with the fixed-threshold global front end\n",
                name, now.at("rot_rmse_deg"), now.at("matches_mean"), now.at("guided_pairs"),
                now.at("fallback_pairs"), before.at("rot_rmse_deg"), before.at("matches_mean"));
    EXPECT_EQ(now.at("invalid"), 0) << name;
    EXPECT_GT(now.at("guided_pairs"), 0.9 * now.at("frames")) << name << ": guided matching should carry the run";
    EXPECT_LE(now.at("rot_rmse_deg"), 1.05 * before.at("rot_rmse_deg")) << name;
  };
  const int compared = forEachSharedSequence({"kitti_turn", "kitti_straight", "euroc_v101_static"}, each);
  if (compared == 0) GTEST_SKIP() << "no shared sequence present under the data folder";
}

TEST(SharedSequences, NativeFrontEndAtLeastAsAccurateAsOrbAndKlt) {
  const auto each = [&](const char* name, const std::string& folder) {
    // The defaults: sub-pixel positions and tracking.
    const Figures native = evaluateVote(folder, "--front-end native");
    // On euroc_v101_static the reference is the gyro (its bias and clock offset removed), whose own
    // angle random walk (ADIS16448: 0.0135 deg/s/sqrt(Hz), about 0.003 deg per axis over a 50 ms
    // pair) is of the size of the errors (about 0.007 deg): a difference below 0.005 deg there is no
    // difference.
    const double tolerance = std::string(name) == "euroc_v101_static" ? 0.005 : 0.0;
    for (const char* other : {"orb", "klt"}) {
      const Figures f = evaluateVote(folder, std::string("--front-end ") + other);
      std::printf("%s: vote rotation RMSE native %.4f deg (%.0f matches), %s %.4f deg (%.0f matches)\n", name,
                  native.at("rot_rmse_deg"), native.at("matches_mean"), other, f.at("rot_rmse_deg"),
                  f.at("matches_mean"));
      EXPECT_LE(native.at("rot_rmse_deg"), f.at("rot_rmse_deg") + tolerance) << name << " against " << other;
    }
  };
  const int compared = forEachSharedSequence({"kitti_turn", "kitti_straight", "euroc_v101_static"}, each);
  if (compared == 0) GTEST_SKIP() << "no shared sequence present under the data folder";
}

// Sub-pixel match positions on the shaken, blurred drone sequence: integer FAST positions leave
// about 0.4 px of quantisation noise on every match (0.05 deg at EuRoC's focal length); the
// alignment removes most of it. Pyramidal LK, sub-pixel by construction, is the yardstick.
TEST(EurocShake, SubpixelPositionsReduceTheErrorToKltLevel) {
  std::string why;
  const std::string folder = sharedOrSkip("euroc_mh01_shake", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  const Figures subpixel = evaluateVote(folder, kSubpixelOnlyFrontEnd);
  const Figures integer = evaluateVote(folder, kIntegerFrontEnd);
  const Figures klt = evaluateVote(folder, "--front-end klt");
  std::printf("euroc_mh01_shake: vote RMSE / max %.4f / %.4f deg sub-pixel, %.4f / %.4f deg integer, "
              "%.4f / %.4f deg on KLT tracks\n",
              subpixel.at("rot_rmse_deg"), subpixel.at("rot_max_deg"), integer.at("rot_rmse_deg"),
              integer.at("rot_max_deg"), klt.at("rot_rmse_deg"), klt.at("rot_max_deg"));
  EXPECT_EQ(subpixel.at("invalid"), 0);
  EXPECT_LE(subpixel.at("rot_rmse_deg"), 0.6 * integer.at("rot_rmse_deg"));
  // The worst frames are valley frames, so only their order is asserted: with integer positions
  // one frame once sat in a wrong basin 0.46 deg off (more than twice the sub-pixel worst frame);
  // the restarts over translation directions found its right basin (0.18 deg, sub-pixel 0.10 deg).
  EXPECT_LT(subpixel.at("rot_max_deg"), integer.at("rot_max_deg"));
  // Within a fifth of KLT in RMSE (tracking closes the rest of the gap: see the next test). The
  // worst frame is not compared with KLT's: it is a valley frame, which depends on which matches
  // were found more than on their positions. Since the guided search covers the last pair's
  // parallax it finds more of the near points' matches, which lowered the RMSE (0.0284 -> 0.0280
  // deg) and moved frame 46's valley step 0.1 deg off (the worst frame was 0.093 deg, 1.15 times
  // KLT's; it is 0.101 deg, 1.25 times).
  EXPECT_LE(subpixel.at("rot_rmse_deg"), 1.2 * klt.at("rot_rmse_deg"));
}

// With tracking as well, the native front end is at least as accurate as KLT on the shaken drone.
// One seed's RMSE moves by a few percent either way there (a few frames' pan lies in the
// rotation/translation valley of the pallet), so both are compared over six estimator seeds.
// Native was within 5 % of KLT but not below it (six-seed means 0.0252 against 0.0247 deg) until
// the guided search covered the last pair's parallax: the near points' matches it had missed put
// native at 0.0240 deg.
TEST(EurocShake, SubpixelPositionsAndTrackingAsAccurateAsKlt) {
  std::string why;
  const std::string folder = sharedOrSkip("euroc_mh01_shake", &why);
  if (folder.empty()) GTEST_SKIP() << why;
  constexpr int kSeeds = 6;
  double native_sum = 0.0, klt_sum = 0.0, native_worst = 0.0;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    const std::string seeded = " --set seed=" + std::to_string(seed);
    const Figures native = evaluateVote(folder, seeded);
    const Figures klt = evaluateVote(folder, "--front-end klt" + seeded);
    std::printf("euroc_mh01_shake, seed %d: vote RMSE %.4f deg native (%.0f matches), %.4f deg KLT\n", seed,
                native.at("rot_rmse_deg"), native.at("matches_mean"), klt.at("rot_rmse_deg"));
    EXPECT_EQ(native.at("invalid"), 0);
    native_sum += native.at("rot_rmse_deg");
    klt_sum += klt.at("rot_rmse_deg");
    native_worst = std::max(native_worst, native.at("rot_rmse_deg"));
  }
  std::printf("mean over %d seeds: native %.4f deg, KLT %.4f deg\n", kSeeds, native_sum / kSeeds, klt_sum / kSeeds);
  EXPECT_LE(native_sum, klt_sum);
  // The tracked corners spread over the weak regions steady the pan: no seed is far off.
  EXPECT_LE(native_worst, 1.1 * native_sum / kSeeds);
}

TEST(RenderedDim, BlurredJpegRoomHasEnoughMatchesForAnAccurateEstimate) {
  const std::string root = visual_gyro::test::makeTempDir("dim");
  run(std::string(VISUAL_GYRO_RENDER) + " --preset dim --frames 25 --blur 3 --jpeg 75 --out " + root + "/dim");
  // The defaults: sub-pixel positions and tracking.
  const Figures now = evaluateVote(root + "/dim", "");
  const Figures before = evaluateVote(root + "/dim", kFixedGlobalFrontEnd);
  std::printf("dim, 3 px blur, JPEG 75: %.1f matches per pair, vote RMSE %.4f deg (fixed-threshold global front "
              "end: %.1f matches, %.0f of %.0f pairs invalid)\n",
              now.at("matches_mean"), now.at("rot_rmse_deg"), before.at("matches_mean"), before.at("invalid"),
              before.at("frames"));
  EXPECT_EQ(now.at("frames"), 24);
  EXPECT_EQ(now.at("invalid"), 0);
  EXPECT_GE(now.at("matches_mean"), 300.0);
  EXPECT_LE(now.at("rot_rmse_deg"), 0.1);
  // Motion blur moves FAST's corners off their content by up to a couple of pixels; sub-pixel
  // alignment of the matches brings them back, and with them more than half of the error (the
  // estimator takes the integer positions' noise-limited general motions for pure rotations, which
  // keeps their error near 0.024 deg; the sub-pixel one is near 0.010 deg).
  const Figures integer = evaluateVote(root + "/dim", kIntegerFrontEnd);
  const Figures subpixel = evaluateVote(root + "/dim", kSubpixelOnlyFrontEnd);
  std::printf("dim, sub-pixel positions: vote RMSE / max %.4f / %.4f deg (integer: %.4f / %.4f deg)\n",
              subpixel.at("rot_rmse_deg"), subpixel.at("rot_max_deg"), integer.at("rot_rmse_deg"),
              integer.at("rot_max_deg"));
  EXPECT_EQ(integer.at("invalid"), 0);
  EXPECT_EQ(subpixel.at("invalid"), 0);
  EXPECT_LE(subpixel.at("rot_rmse_deg"), 0.5 * integer.at("rot_rmse_deg"));
  // Most low-contrast corners are found by FAST in one frame only: tracking makes them count, and
  // the roll (which needs many matches far from the centre) comes close to KLT's. The rendering is
  // deterministic and so is this RMSE (no seed dependence).
  const Figures& tracking = now;
  const Figures klt = evaluateVote(root + "/dim", "--front-end klt");
  std::printf("dim, sub-pixel positions and tracking: %.1f matches, vote RMSE / max %.4f / %.4f deg; KLT: %.1f "
              "tracks, %.4f / %.4f deg\n",
              tracking.at("matches_mean"), tracking.at("rot_rmse_deg"), tracking.at("rot_max_deg"),
              klt.at("matches_mean"), klt.at("rot_rmse_deg"), klt.at("rot_max_deg"));
  EXPECT_GE(tracking.at("matches_mean"), 1.8 * subpixel.at("matches_mean"));
  EXPECT_LE(tracking.at("rot_rmse_deg"), 0.97 * subpixel.at("rot_rmse_deg"));
  // Not yet at least as accurate as KLT here (3-6 % behind with 25 or 40 frames): within a tenth.
  EXPECT_LE(tracking.at("rot_rmse_deg"), 1.1 * klt.at("rot_rmse_deg"));
}

namespace {

/// How much further than the 99.9 % bound a valid frame's NEES may lie: a factor of 4, an error
/// twice the bound's radius. Beyond that a frame is plainly wrong, not unlucky.
constexpr double kFarBeyondFactor = 4.0;

/// Normalised squared errors of the valid frames of a static camera: the estimate's error against
/// the gyro (which evaluate has already de-biased and aligned), less any constant error left (the
/// mean error), over the covariance's per-axis variances (the CSV gives the diagonal). There is no
/// pose truth to judge the covariance by.
std::vector<double> staticNormalisedErrors(const std::vector<std::map<std::string, std::string>>& rows) {
  std::vector<std::array<double, 6>> frames;  // error x y z, sigma x y z [deg]
  for (const auto& row : rows) {
    if (row.at("valid") != "1") continue;
    std::array<double, 6> f{};
    const char* keys[6] = {"err_x_deg", "err_y_deg", "err_z_deg", "sigma_x_deg", "sigma_y_deg", "sigma_z_deg"};
    bool complete = true;  // a frame the aligned gyro does not cover has no error to judge
    for (int k = 0; k < 6; ++k) {
      const std::string& cell = row.at(keys[k]);
      complete = complete && !cell.empty();
      if (complete) f[k] = std::stod(cell);
    }
    if (complete) frames.push_back(f);
  }
  std::array<double, 3> bias{};
  for (const auto& f : frames)
    for (int k = 0; k < 3; ++k) bias[k] += f[k] / frames.size();
  std::vector<double> q;
  for (const auto& f : frames) {
    double sum = 0.0;
    for (int k = 0; k < 3; ++k) sum += (f[k] - bias[k]) * (f[k] - bias[k]) / (f[3 + k] * f[3 + k]);
    q.push_back(sum);
  }
  return q;
}

}  // namespace

// Footage of a lower-resolution camera (evaluate --scale: the images downscaled, the intrinsics
// with them). At every scale the covariance is honest on the frames the estimator calls valid, or
// the frames are invalid; no valid frame lies far beyond the 99.9 % bound; and the resolutions the
// estimator handles (a quarter and half of the originals) keep all their frames. Below them (0.15,
// 0.1 of the originals) the descriptor's border leaves a band of the image whose matches cover
// fewer than kMinDescriptorAreas descriptor patches, and the estimates there were 5 to 20 times
// further off than their covariance said. 30 frames a case.
TEST(SharedSequences, DownscaledFootageIsHonestOrInvalid) {
  const auto each = [&](const char* name, const std::string& folder) {
    const bool has_poses = std::string(name) != "euroc_v101_static";
    for (const double scale : {0.1, 0.15, 0.25, 0.5}) {
      char extra[160];
      const std::string csv = visual_gyro::test::makeTempDir("scaled") + "/frames.csv";
      std::snprintf(extra, sizeof(extra), "--scale %g --frames 30 --csv %s", scale, csv.c_str());
      const Figures f = evaluate(folder, "vote", extra);
      SCOPED_TRACE(std::string(name) + " at scale " + extra);
      EXPECT_EQ(f.at("vote.scale"), scale);
      const int valid = static_cast<int>(f.at("vote.frames") - f.at("vote.invalid"));
      std::vector<double> nees;
      if (has_poses) {
        for (const auto& row : readFrameRows(csv))
          if (row.at("valid") == "1" && !row.at("nees").empty()) nees.push_back(std::stod(row.at("nees")));
        EXPECT_EQ(static_cast<int>(nees.size()), valid);
      } else if (valid > 0) {
        nees = staticNormalisedErrors(readFrameRows(csv));
      }
      double sum = 0.0, largest = 0.0;
      int beyond = 0;
      for (double q : nees) {
        sum += q;
        largest = std::max(largest, q);
        beyond += q > visual_gyro::metrics::kChiSquare3Dof99;
      }
      const double mean = nees.empty() ? NAN : sum / nees.size();
      std::printf("%s at scale %.2f: %d of %d frames valid, NEES mean %.2f, %d beyond the 99 %% bound, largest %.1f%s\n",
                  name, scale, valid, static_cast<int>(f.at("vote.frames")), mean, beyond, largest,
                  has_poses ? "" : " (against the gyro less its bias, diagonal covariance)");
      EXPECT_LE(largest, kFarBeyondFactor * visual_gyro::metrics::kChiSquare3Dof999);
      if (scale >= 0.25) EXPECT_LE(f.at("vote.invalid"), 0.1 * f.at("vote.frames")) << "a usable resolution";
      if (valid < 10) continue;  // a mean over fewer frames says little; the bound above holds
      if (has_poses) {
        expectHonestCovariance(f, "vote");
      } else {
        // A standing camera's errors lie below the covariance's floor for unmodelled errors, so only
        // over-confidence is judged.
        EXPECT_LE(mean, 6.0);
        EXPECT_LE(beyond, 0.05 * nees.size());
      }
    }
  };
  const int judged =
      forEachSharedSequence({"kitti_turn", "kitti_straight", "euroc_mh01_shake", "euroc_v101_static"}, each);
  if (judged == 0) GTEST_SKIP() << "no shared sequence present under the data folder";
}
