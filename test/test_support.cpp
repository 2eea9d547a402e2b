#include "test_support.h"

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>

#include <sys/wait.h>

namespace visual_gyro {
namespace test {

RenderSettings handheldRoom(int width, int height, double focal) {
  RenderSettings s;
  s.preset = RenderPreset::kHandheld;
  s.setCentredCamera(width, height, focal);
  return s;
}

CameraModel cameraOf(const RenderSettings& scene) {
  return CameraModel(scene.fx, scene.fy, scene.cx, scene.cy, scene.width, scene.height);
}

VisualGyroSettings cpuSettings() {
  VisualGyroSettings s;
  s.estimator.backend = BackendChoice::kCpu;
  return s;
}

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

std::string runCommand(const std::string& command, int* status) {
  std::string output;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) {
    *status = -1;
    return output;
  }
  std::array<char, 4096> buffer;
  while (fgets(buffer.data(), buffer.size(), pipe) != nullptr) output += buffer.data();
  const int raw = pclose(pipe);
  *status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  return output;
}

double jsonNumber(const std::string& line, const std::string& key) {
  const std::string needle = "\"" + key + "\": ";
  const size_t at = line.find(needle);
  if (at == std::string::npos) return std::nan("");
  const char* value = line.c_str() + at + needle.size();
  char* end = nullptr;
  const double number = std::strtod(value, &end);
  return end == value ? std::nan("") : number;  // e.g. null: no such figure for this sequence
}

std::string jsonString(const std::string& line, const std::string& key) {
  const std::string needle = "\"" + key + "\": \"";
  const size_t at = line.find(needle);
  if (at == std::string::npos) return "";
  const size_t end = line.find('"', at + needle.size());
  return line.substr(at + needle.size(), end - at - needle.size());
}

}  // namespace test
}  // namespace visual_gyro
