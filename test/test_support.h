// Helpers shared by the unit tests.
#pragma once

#include <string>

#include "visual_gyro/camera_model.h"
#include "visual_gyro/renderer.h"
#include "visual_gyro/visual_gyro.h"

namespace visual_gyro {
namespace test {

/// The hand-held room preset rendered at width x height with focal length `focal` [px], centred.
RenderSettings handheldRoom(int width, int height, double focal);
/// The pinhole camera of rendered views (no distortion).
CameraModel cameraOf(const RenderSettings& scene);
/// Default pipeline settings on the CPU backend (the tests' figures must not depend on a GPU).
VisualGyroSettings cpuSettings();

/// Folder of the shared real sequences: $VISUAL_GYRO_DATA, else ../shared/data beside the repo.
std::string sharedDataDir();
/// Path of a shared sequence, or "" (with the reason in *why) when it is absent.
std::string sharedSequence(const std::string& name, std::string* why);
/// A fresh temporary folder for one test.
std::string makeTempDir(const std::string& tag);
/// Runs a shell command (stderr merged into stdout) and returns its output; *status receives the
/// exit status (-1 when it could not be started).
std::string runCommand(const std::string& command, int* status);
/// The number under "key" in one of evaluate's JSON lines; NaN when absent or null.
double jsonNumber(const std::string& line, const std::string& key);
/// The string under "key" in one of evaluate's JSON lines; "" when absent.
std::string jsonString(const std::string& line, const std::string& key);

}  // namespace test
}  // namespace visual_gyro
