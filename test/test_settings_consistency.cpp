// One source of truth for the settings: the C++ defaults, cfg/VisualGyro.cfg, config/visual_gyro.yaml
// and the README's tables must agree. Fails when a copy drifts.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>

#include "visual_gyro/visual_gyro.h"

namespace fs = std::filesystem;

namespace {

fs::path repo() { return fs::path(__FILE__).parent_path().parent_path(); }

std::string readAll(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// name -> default of every gen.add(...) in the .cfg.
std::map<std::string, std::string> cfgDefaults() {
  std::map<std::string, std::string> out;
  const std::string text = readAll(repo() / "cfg" / "VisualGyro.cfg");
  const std::regex add(R"re(gen\.add\("(\w+)",\s*\w+,\s*\d+,\s*"[^"]*",\s*("[^"]*"|[^,\s)]+))re");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), add); it != std::sregex_iterator(); ++it)
    out[(*it)[1]] = (*it)[2];
  return out;
}

/// name -> value of every top-level "name: value" line in the yaml.
std::map<std::string, std::string> yamlValues() {
  std::map<std::string, std::string> out;
  std::ifstream in(repo() / "config" / "visual_gyro.yaml");
  std::string line;
  const std::regex entry(R"re(^(\w+):\s*("[^"]*"|[^#\s]+))re");
  while (std::getline(in, line)) {
    std::smatch m;
    if (std::regex_search(line, m, entry)) out[m[1]] = m[2];
  }
  return out;
}

bool sameValue(const std::string& a, const std::string& b) {
  auto norm = [](std::string s) {
    if (s == "True") return std::string("true");
    if (s == "False") return std::string("false");
    if (!s.empty() && s.front() == '"') s = s.substr(1, s.size() - 2);
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (end != s.c_str() && *end == '\0') {
      std::ostringstream o;
      o << v;
      return o.str();
    }
    return s;
  };
  return norm(a) == norm(b);
}

}  // namespace

TEST(SettingsConsistency, CfgYamlAndReadmeAgree) {
  const auto cfg = cfgDefaults();
  const auto yaml = yamlValues();
  const std::string readme = readAll(repo() / "README.md");
  ASSERT_GT(cfg.size(), 30u) << "the .cfg was not parsed";
  for (const auto& entry : cfg) {
    const auto y = yaml.find(entry.first);
    ASSERT_NE(y, yaml.end()) << entry.first << " is in the .cfg but not in config/visual_gyro.yaml";
    EXPECT_TRUE(sameValue(entry.second, y->second))
        << entry.first << ": .cfg default " << entry.second << ", yaml " << y->second;
    EXPECT_NE(readme.find("`" + entry.first + "`"), std::string::npos) << entry.first << " is not in the README";
  }
}

TEST(SettingsConsistency, PlausibilityDefaultsMatchTheCode) {
  const auto cfg = cfgDefaults();
  const visual_gyro::VisualGyroSettings defaults;
  ASSERT_TRUE(cfg.count("min_dt") && cfg.count("max_rate_dps"));
  EXPECT_DOUBLE_EQ(std::stod(cfg.at("min_dt")), defaults.min_dt);
  EXPECT_DOUBLE_EQ(std::stod(cfg.at("max_rate_dps")), defaults.max_rate_dps);
  const auto yaml = yamlValues();
  ASSERT_TRUE(yaml.count("mono16_bit_depth"));
  EXPECT_EQ(yaml.at("mono16_bit_depth"), "0");
}
