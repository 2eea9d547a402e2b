#include "test_support.h"

#include <cstdlib>
#include <filesystem>
#include <random>

namespace visual_gyro {
namespace test {

std::string sharedDataDir() {
  const char* env = std::getenv("VISUAL_GYRO_DATA");
  if (env != nullptr && *env != '\0') return env;
  return VISUAL_GYRO_DEFAULT_DATA;
}

std::string sharedSequence(const std::string& name, std::string* why) {
  const std::filesystem::path path = std::filesystem::path(sharedDataDir()) / name;
  if (!std::filesystem::is_directory(path)) {
    *why = "shared sequence " + path.string() +
           " is absent (set VISUAL_GYRO_DATA or put ../shared/data beside the repo)";
    return "";
  }
  return path.string();
}

std::string makeTempDir(const std::string& tag) {
  std::random_device rd;
  const auto path = std::filesystem::temp_directory_path() /
                    ("visual_gyro_" + tag + "_" + std::to_string(rd()));
  std::filesystem::create_directories(path);
  return path.string();
}

}  // namespace test
}  // namespace visual_gyro
