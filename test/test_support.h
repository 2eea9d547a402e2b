// Helpers shared by the unit tests.
#pragma once

#include <string>

namespace visual_gyro {
namespace test {

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
