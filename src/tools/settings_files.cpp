// settings_files: writes the files made from the settings tables (cfg/VisualGyro.cfg,
// config/visual_gyro.yaml, the settings blocks of README.md and doc/ros.md) into a checkout, or,
// with --check, says which differ. `make settings-files` runs it on this checkout.
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <stdexcept>

#include "command_line.h"
#include "settings_text.h"

namespace {

namespace fs = std::filesystem;
namespace st = visual_gyro::settings_text;

const char* kUsage =
    "usage: settings_files [--check] REPO_DIR\n"
    "  writes cfg/VisualGyro.cfg, config/visual_gyro.yaml and the settings blocks between the markers\n"
    "  of README.md and doc/ros.md from the settings tables\n"
    "  --check   write nothing; list the files that differ and exit 1 when any does\n";

std::string readFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path.string());
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

void writeFile(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

int run(const fs::path& repo, bool check) {
  // Parts of one file are applied in turn to its text, read once.
  std::map<std::string, std::string> before, after;
  for (const st::GeneratedPart& part : st::generatedParts()) {
    if (!after.count(part.path)) {
      const fs::path path = repo / part.path;
      before[part.path] = part.begin.empty() && !fs::exists(path) ? std::string() : readFile(path);
      after[part.path] = before[part.path];
    }
    std::string updated, why;
    if (!st::applyPart(after[part.path], part, &updated, &why)) throw std::runtime_error(why);
    after[part.path] = updated;
  }
  int differing = 0;
  for (const auto& file : after) {
    if (file.second == before[file.first]) continue;
    ++differing;
    if (check) {
      std::cout << file.first << " differs from the settings tables\n";
    } else {
      writeFile(repo / file.first, file.second);
      std::cout << "wrote " << file.first << "\n";
    }
  }
  if (check && differing > 0) std::cout << "run `" << st::kRegenerateCommand << "` to regenerate them\n";
  return check && differing > 0 ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  return visual_gyro::cli::runCommand("settings_files", kUsage, [&] {
    bool check = false;
    std::vector<std::string> positional;
    for (visual_gyro::cli::Arguments args(argc, argv); args.next();) {
      if (args.is("--check")) {
        check = true;
      } else {
        args.positional(&positional, 1);
      }
    }
    if (positional.empty()) throw visual_gyro::cli::UsageError("REPO_DIR is missing");
    if (!fs::is_directory(positional[0])) throw std::runtime_error(positional[0] + " is not a folder");
    return run(positional[0], check);
  });
}
