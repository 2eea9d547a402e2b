// The CPU level every kernel is chosen by (src/core/cpu_features.h): its names, the clamping of a
// forced level, the one selector, and that forcing any level the CPU has changes no result of the
// commands (every kernel of a level gives the portable kernels' results bit for bit).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

#include "cpu_features.h"
#include "test_support.h"

namespace visual_gyro {
namespace {

TEST(CpuLevel, NamesRoundTripAndUnknownNamesAreRejected) {
  for (const cpu::CpuLevel level : cpu::kAllLevels) {
    cpu::CpuLevel parsed = cpu::CpuLevel::kPortable;
    ASSERT_TRUE(cpu::parseLevel(cpu::levelName(level), &parsed)) << cpu::levelName(level);
    EXPECT_EQ(parsed, level);
  }
  cpu::CpuLevel untouched = cpu::CpuLevel::kAvx;
  EXPECT_FALSE(cpu::parseLevel("avx512", &untouched));
  EXPECT_FALSE(cpu::parseLevel("", &untouched));
  EXPECT_EQ(untouched, cpu::CpuLevel::kAvx);
}

TEST(CpuLevel, AForcedLevelIsClampedToTheCpus) {
  EXPECT_EQ(cpu::clampLevel(cpu::CpuLevel::kAvx512Vbmi, cpu::CpuLevel::kAvx2), cpu::CpuLevel::kAvx2);
  EXPECT_EQ(cpu::clampLevel(cpu::CpuLevel::kSse2, cpu::CpuLevel::kAvx2), cpu::CpuLevel::kSse2);
  EXPECT_LE(static_cast<int>(cpu::activeLevel()), static_cast<int>(cpu::detectedLevel()));
#if defined(__x86_64__)
  EXPECT_GE(static_cast<int>(cpu::detectedLevel()), static_cast<int>(cpu::CpuLevel::kSse2));
#endif
  std::printf("this CPU: %s; kernels chosen for %s\n", cpu::levelName(cpu::detectedLevel()),
              cpu::levelName(cpu::activeLevel()));
}

// Three kernels of a made-up family, at kPortable, kPopcnt and kAvx2.
int portableKernel() { return 0; }
int popcntKernel() { return 2; }
int avx2Kernel() { return 4; }
using FakeKernel = int (*)();
FakeKernel fakeKernelFor(cpu::CpuLevel level) {
  switch (level) {
    case cpu::CpuLevel::kPortable:
      return portableKernel;
    case cpu::CpuLevel::kPopcnt:
      return popcntKernel;
    case cpu::CpuLevel::kAvx2:
      return avx2Kernel;
    default:
      return nullptr;
  }
}

TEST(CpuLevel, TheSelectorTakesTheHighestLevelWithAKernel) {
  EXPECT_EQ(cpu::selectKernel(fakeKernelFor, cpu::CpuLevel::kAvx512Vbmi), avx2Kernel);
  EXPECT_EQ(cpu::selectKernel(fakeKernelFor, cpu::CpuLevel::kAvx2), avx2Kernel);
  EXPECT_EQ(cpu::selectKernel(fakeKernelFor, cpu::CpuLevel::kAvx), popcntKernel);
  EXPECT_EQ(cpu::selectKernel(fakeKernelFor, cpu::CpuLevel::kSse2), portableKernel);
  EXPECT_EQ(cpu::selectKernel(fakeKernelFor, cpu::CpuLevel::kPortable), portableKernel);
  // A lower bound: none when no level from the bound up to the highest has one.
  EXPECT_EQ(cpu::selectKernel(fakeKernelFor, cpu::CpuLevel::kSse2, cpu::CpuLevel::kSse2), nullptr);
  EXPECT_EQ(cpu::selectKernel(fakeKernelFor, cpu::CpuLevel::kAvx, cpu::CpuLevel::kSse2), popcntKernel);
}

std::string fileText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The whole front end (Gaussian, FAST, BRIEF, Hamming search, patch alignment) and the estimator
// (triple solver, per-match passes) at every level this CPU has, forced through the environment:
// the exported bearings and the figures are the same as at the CPU's own level.
TEST(CpuLevel, EveryForcedLevelGivesTheSameBearingsAndFigures) {
  const std::string dir = test::makeTempDir("cpu_level");
  int status = 0;
  std::string out = test::runCommand(std::string(VISUAL_GYRO_RENDER) + " --preset drive --frames 8 --out " + dir +
                                         "/drive",
                                     &status);
  ASSERT_EQ(status, 0) << out;
  auto evaluate = [&](const std::string& level, const std::string& bearings) {
    const std::string env = level.empty() ? "" : std::string(cpu::kLevelVariable) + "=" + level + " ";
    return test::runCommand(env + VISUAL_GYRO_EVALUATE + " " + dir + "/drive --method vote --backend cpu --quiet" +
                                " --export-bearings " + bearings,
                            &status);
  };
  const std::string reference_out = evaluate("", dir + "/own.txt");
  ASSERT_EQ(status, 0) << reference_out;
  const std::string reference = fileText(dir + "/own.txt");
  ASSERT_GT(reference.size(), 1000u);
  const double rmse = test::jsonNumber(reference_out, "rot_rmse_deg");
  ASSERT_FALSE(std::isnan(rmse)) << reference_out;
  int levels = 0;
  for (const cpu::CpuLevel level : cpu::kAllLevels) {
    if (!cpu::runs(level)) continue;
    const std::string path = dir + "/" + cpu::levelName(level) + ".txt";
    out = evaluate(cpu::levelName(level), path);
    ASSERT_EQ(status, 0) << out;
    EXPECT_TRUE(fileText(path) == reference) << "bearings differ at level " << cpu::levelName(level);
    EXPECT_EQ(test::jsonNumber(out, "rot_rmse_deg"), rmse) << cpu::levelName(level);
    ++levels;
  }
  EXPECT_GE(levels, 1);
  // An unknown name is reported and the CPU's own level used.
  out = evaluate("sse5", dir + "/unknown.txt");
  ASSERT_EQ(status, 0) << out;
  EXPECT_NE(out.find("is no level"), std::string::npos) << out;
  EXPECT_TRUE(fileText(dir + "/unknown.txt") == reference);
}

}  // namespace
}  // namespace visual_gyro
