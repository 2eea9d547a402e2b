// The catkin workspace's view of the package (scripts/build.sh): ROS's command-line tools find it
// without a warning on stderr (a workspace link back into the repository, which holds build/ and
// so the workspace itself, made `rosrun` print "File system loop detected"), and the package they
// find is this repository.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "test_support.h"

namespace {

namespace fs = std::filesystem;

/// Runs `command` with Debian's python first in PATH (ROS's tools need it); its stdout in `out`
/// (when given), its stderr returned.
std::string stderrOf(const std::string& command, std::string* out = nullptr, int* status = nullptr) {
  const std::string err_file = visual_gyro::test::makeTempDir("layout") + "/stderr";
  int s = 0;
  const std::string stdout_text =
      visual_gyro::test::runCommand("PATH=/usr/bin:/bin:$PATH " + command + " 2>" + err_file, &s);
  if (out) *out = stdout_text;
  if (status) *status = s;
  std::string err;
  int ignored = 0;
  err = visual_gyro::test::runCommand("cat " + err_file, &ignored);
  fs::remove_all(fs::path(err_file).parent_path());
  return err;
}

TEST(WorkspaceLayout, RospackFindsThisRepositoryWithoutWarnings) {
  std::string out;
  int status = 0;
  const std::string err = stderrOf("rospack find visual_gyro", &out, &status);
  EXPECT_EQ(status, 0);
  EXPECT_EQ(err, "") << "rospack wrote to stderr";
  while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
  ASSERT_FALSE(out.empty());
  EXPECT_EQ(fs::canonical(out + "/package.xml"), fs::canonical(std::string(VISUAL_GYRO_REPO_DIR) + "/package.xml"));
  EXPECT_FALSE(fs::exists(out + "/build")) << "the package folder ROS crawls holds the build folder";
}

TEST(WorkspaceLayout, RosrunAndRoslaunchWithoutWarnings) {
  int status = 0;
  std::string out;
  std::string err = stderrOf("rosrun visual_gyro make_bag --help", &out, &status);
  EXPECT_EQ(err.find("File system loop"), std::string::npos) << err;
  EXPECT_EQ(err.find("arning"), std::string::npos) << err;
  EXPECT_NE(out.find("usage: make_bag"), std::string::npos) << out << err;
  err = stderrOf("roslaunch --files visual_gyro visual_gyro.launch", &out, &status);
  EXPECT_EQ(status, 0) << err;
  EXPECT_EQ(err, "") << "roslaunch wrote to stderr";
  EXPECT_NE(out.find("visual_gyro.launch"), std::string::npos) << out;
}

}  // namespace
