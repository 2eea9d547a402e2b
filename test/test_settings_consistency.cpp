// One source of truth for the settings: the pipeline's table (visualGyroSettingFields) and the
// node's (nodeSettingFields) against the files made from them (cfg/VisualGyro.cfg,
// config/visual_gyro.yaml, the settings blocks of README.md and doc/ros.md) and against the gate.
// Fails when a committed file differs from what `make settings-files` writes, when the generated
// files do not say what the tables say, or when the gate accepts other values than the ranges.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "node_settings.h"
#include "settings_text.h"
#include "visual_gyro/camera_model.h"
#include "visual_gyro/visual_gyro.h"

namespace fs = std::filesystem;
namespace vg = visual_gyro;
namespace st = visual_gyro::settings_text;

namespace {

// The checkout (in the catkin workspace: its shadow folder of links to the checkout's entries).
fs::path repo() { return fs::path(VISUAL_GYRO_SOURCE_DIR); }

std::string readAll(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// One gen.add(...) of the .cfg.
struct CfgEntry {
  std::string type;  ///< int_t, double_t, bool_t, str_t
  std::string default_text;
  std::vector<std::string> choices;  ///< str_t with an edit_method enum
};

/// The enum constants of every gen.enum([...]) assigned to a Python name.
std::map<std::string, std::vector<std::string>> cfgEnums(const std::string& text) {
  std::map<std::string, std::vector<std::string>> out;
  const std::regex assign(R"re((\w+)\s*=\s*gen\.enum\(\[([\s\S]*?)\]\s*,)re");
  const std::regex constant(R"re(gen\.const\("\w+",\s*str_t,\s*"([^"]*)")re");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), assign); it != std::sregex_iterator(); ++it) {
    const std::string body = (*it)[2];
    for (auto c = std::sregex_iterator(body.begin(), body.end(), constant); c != std::sregex_iterator(); ++c)
      out[(*it)[1]].push_back((*c)[1]);
  }
  return out;
}

/// name -> gen.add(...) of cfg/VisualGyro.cfg, read as dynamic_reconfigure reads it.
std::map<std::string, CfgEntry> cfgEntries() {
  std::map<std::string, CfgEntry> out;
  const std::string text = readAll(repo() / "cfg" / "VisualGyro.cfg");
  const auto enums = cfgEnums(text);
  // gen.add("name", type, level, "doc", default[, edit_method=enum]): no min, no max.
  const std::regex add(
      R"re(gen\.add\("(\w+)",\s*(\w+),\s*\d+,\s*"(?:[^"\\]|\\.)*",\s*("(?:[^"\\]|\\.)*"|[^,\s)]+)(?:,\s*edit_method=(\w+))?\))re");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), add); it != std::sregex_iterator(); ++it) {
    CfgEntry e;
    e.type = (*it)[2];
    e.default_text = (*it)[3];
    const std::string edit = (*it)[4];
    if (!edit.empty() && enums.count(edit)) e.choices = enums.at(edit);
    out[(*it)[1]] = e;
  }
  return out;
}

/// name -> value of every top-level "name: value" line in the yaml.
std::map<std::string, std::string> yamlValues() {
  std::map<std::string, std::string> out;
  std::ifstream in(repo() / "config" / "visual_gyro.yaml");
  std::string line;
  const std::regex entry(R"re(^(\w+):\s*("[^"]*"|\[[^\]]*\]|[^#\s]+))re");
  while (std::getline(in, line)) {
    std::smatch m;
    if (std::regex_search(line, m, entry)) out[m[1]] = m[2];
  }
  return out;
}

/// Python / YAML / C++ spellings of one value, made comparable.
std::string normalised(std::string s) {
  if (s == "True") return "true";
  if (s == "False") return "false";
  if (!s.empty() && s.front() == '"') s = s.substr(1, s.size() - 2);
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (!s.empty() && end != s.c_str() && *end == '\0') {
    std::ostringstream o;
    o.precision(12);
    o << v;
    return o.str();
  }
  return s;
}

const char* cfgType(vg::SettingType type) {
  switch (type) {
    case vg::SettingType::kBool: return "bool_t";
    case vg::SettingType::kInt: return "int_t";
    case vg::SettingType::kDouble: return "double_t";
    case vg::SettingType::kString: return "str_t";
    case vg::SettingType::kDoubleList: return "(none: not live)";
  }
  return "?";
}

/// The first line where `a` and `b` differ, for the failure message.
std::string firstDifference(const std::string& a, const std::string& b) {
  std::istringstream in_a(a), in_b(b);
  std::string line_a, line_b;
  for (int line = 1;; ++line) {
    const bool more_a = static_cast<bool>(std::getline(in_a, line_a));
    const bool more_b = static_cast<bool>(std::getline(in_b, line_b));
    if (!more_a && !more_b) return "(they differ in line endings only)";
    if (!more_a || !more_b || line_a != line_b) {
      return "line " + std::to_string(line) + ":\n  committed: " + (more_a ? line_a : "(end)") +
             "\n  generated: " + (more_b ? line_b : "(end)");
    }
  }
}

}  // namespace

TEST(SettingsConsistency, CommittedFilesAreWhatTheTablesGenerate) {
  std::map<std::string, std::string> committed, generated;
  for (const st::GeneratedPart& part : st::generatedParts()) {
    if (!committed.count(part.path)) {
      committed[part.path] = readAll(repo() / part.path);
      generated[part.path] = committed[part.path];
    }
    std::string updated, why;
    ASSERT_TRUE(st::applyPart(generated[part.path], part, &updated, &why)) << why;
    generated[part.path] = updated;
  }
  for (const auto& file : committed) {
    EXPECT_TRUE(file.second == generated[file.first])
        << file.first << " differs from the settings tables; run `" << st::kRegenerateCommand
        << "` to regenerate it. First difference at " << firstDifference(file.second, generated[file.first]);
  }
}

// The generated files say what the tables say, read as dynamic_reconfigure and rosparam read them.
TEST(SettingsConsistency, CfgAndYamlHoldEverySettingWithItsDefault) {
  const auto cfg = cfgEntries();
  const auto yaml = yamlValues();
  const auto all = vg::everySetting();
  ASSERT_GT(all.size(), 60u);
  size_t live = 0;
  for (const vg::AnySetting& s : all) {
    SCOPED_TRACE(s.spec->name);
    const auto y = yaml.find(s.spec->name);
    ASSERT_NE(y, yaml.end()) << "not in config/visual_gyro.yaml";
    if (s.spec->type == vg::SettingType::kDouble) {
      // PyYAML reads a float only with a point: "1e-08" would be text.
      EXPECT_TRUE(std::regex_match(y->second, std::regex(R"re([-+]?[0-9]+\.[0-9]*([eE][-+][0-9]+)?)re")))
          << "yaml " << y->second << " is no YAML 1.1 float";
    }
    if (s.spec->type == vg::SettingType::kDoubleList) {
      EXPECT_EQ(y->second, "[]");
      EXPECT_FALSE(s.spec->live) << "dynamic_reconfigure has no list type";
    } else {
      EXPECT_EQ(normalised(y->second), normalised(s.default_text)) << "yaml " << y->second;
    }
    const auto c = cfg.find(s.spec->name);
    if (!s.spec->live) {
      EXPECT_EQ(c, cfg.end()) << "read once at start: not in the .cfg";
      continue;
    }
    ++live;
    ASSERT_NE(c, cfg.end()) << "live but not in cfg/VisualGyro.cfg";
    EXPECT_EQ(c->second.type, cfgType(s.spec->type));
    EXPECT_EQ(normalised(c->second.default_text), normalised(s.default_text));
    EXPECT_EQ(c->second.choices, s.spec->choices) << "enum constants differ";
  }
  EXPECT_EQ(cfg.size(), live) << "the .cfg holds a parameter that is no live setting";
}

TEST(SettingsConsistency, EverySettingIsNamedInDocRos) {
  const std::string doc = readAll(repo() / "doc" / "ros.md");
  ASSERT_FALSE(doc.empty()) << "cannot read doc/ros.md";
  for (const vg::AnySetting& s : vg::everySetting())
    EXPECT_NE(doc.find("`" + s.spec->name + "`"), std::string::npos) << s.spec->name << " is not in doc/ros.md";
}

TEST(SettingsConsistency, TiersNamesAndDefaults) {
  std::set<std::string> names, user, paper;
  for (const vg::AnySetting& s : vg::everySetting()) {
    EXPECT_TRUE(names.insert(s.spec->name).second) << s.spec->name << " is in both tables";
    if (s.spec->tier == vg::SettingTier::kUser) user.insert(s.spec->name);
    if (s.spec->tier == vg::SettingTier::kPaperOnly) paper.insert(s.spec->name);
    EXPECT_FALSE(s.spec->doc.empty()) << s.spec->name;
    EXPECT_EQ(s.spec->doc.find('|'), std::string::npos) << s.spec->name << ": a '|' breaks the Markdown tables";
  }
  EXPECT_EQ(paper, (std::set<std::string>{"centroid_subtraction", "yaw_bin_deg", "yaw_window_deg"}));
  EXPECT_GE(user.size(), 8u);
  EXPECT_LE(user.size(), 14u) << "the user tier is the few settings a user sets";
  EXPECT_EQ(names.count("run_estimator"), 0u) << "an option of the evaluation, not a setting";
  // The defaults pass the gate.
  EXPECT_EQ(vg::validateVisualGyroSettings(vg::VisualGyroSettings()), "");
  EXPECT_EQ(vg::validateNodeSettings(vg::NodeSettings()), "");
  // Every distortion model the node accepts is one the camera model knows.
  for (const std::string& model : vg::findNodeSetting("distortion_model")->choices)
    EXPECT_TRUE(vg::parseDistortionModel(model, nullptr)) << model;
}

// The gate accepts exactly the ranges, for both tables: both ends of every range are valid (an
// exclusive end is not), the first value beyond each end is refused naming the setting, and so
// are NaN and infinities; through the table's own apply function and through checkSettingValue.
TEST(SettingsConsistency, ValidationAcceptsExactlyTheRanges) {
  for (const vg::AnySetting& s : vg::everySetting()) {
    const vg::SettingSpec& f = *s.spec;
    if (f.type == vg::SettingType::kBool || f.type == vg::SettingType::kString) continue;
    SCOPED_TRACE(f.name);
    const bool integer = f.type == vg::SettingType::kInt;
    const double step = integer ? 1.0 : std::max(1e-9, 1e-6 * std::abs(f.max - f.min));
    auto text = [&](double v) {
      const std::string number = integer ? std::to_string(static_cast<long long>(v)) : vg::SettingSpec::formatNumber(v);
      return f.type == vg::SettingType::kDoubleList ? "[" + number + "]" : number;
    };
    auto check = [&](double v) {
      const std::string why = vg::checkSettingValue(f.name, text(v));
      // The same answer through the table's own apply function, and a refused value changes nothing.
      if (s.node) {
        vg::NodeSettings settings;
        EXPECT_EQ(vg::applyNodeSetting(&settings, f.name, text(v)), why);
        EXPECT_EQ(vg::validateNodeSettings(settings), "") << "a refused value changed the settings";
      } else {
        vg::VisualGyroSettings settings;
        EXPECT_EQ(vg::applySetting(&settings, f.name, text(v)), why);
        EXPECT_EQ(vg::validateVisualGyroSettings(settings), "") << "a refused value changed the settings";
      }
      return why;
    };
    EXPECT_EQ(check(f.max), "") << text(f.max);
    if (f.min_exclusive) {
      EXPECT_EQ(check(f.min + step), "") << text(f.min + step);
      EXPECT_NE(check(f.min).find(f.name), std::string::npos) << text(f.min) << " accepted at an exclusive end";
    } else {
      EXPECT_EQ(check(f.min), "") << text(f.min);
    }
    if (f.has_special) EXPECT_EQ(check(f.special), "") << "special value " << text(f.special);
    for (const double outside : {f.min - step, f.max + step}) {
      if (f.name == "seed" && outside < 0) continue;  // unsigned: not representable
      if (f.has_special && outside == f.special) continue;
      EXPECT_NE(check(outside).find(f.name), std::string::npos) << text(outside) << " accepted";
    }
    for (const char* bad : {"nan", "inf", "-inf"}) {
      const std::string value = f.type == vg::SettingType::kDoubleList ? std::string("[") + bad + "]" : bad;
      EXPECT_NE(vg::checkSettingValue(f.name, value).find(f.name), std::string::npos) << value << " accepted";
    }
  }
  // Text that is no value of its type, and unknown names, are refused too, naming the setting.
  EXPECT_NE(vg::checkSettingValue("hypotheses", "many").find("hypotheses"), std::string::npos);
  EXPECT_NE(vg::checkSettingValue("cross_check", "perhaps").find("cross_check"), std::string::npos);
  EXPECT_NE(vg::checkSettingValue("matching", "sideways").find("guided, global"), std::string::npos);
  EXPECT_NE(vg::checkSettingValue("queue_size", "1.5").find("queue_size"), std::string::npos);
  EXPECT_NE(vg::checkSettingValue("D", "[1, x]").find("D"), std::string::npos);
  EXPECT_NE(vg::checkSettingValue("distortion_model", "fisheye-ish").find("distortion_model"), std::string::npos);
  EXPECT_NE(vg::checkSettingValue("no_such_setting", "1").find("unknown setting"), std::string::npos);
}

// The values that were stored silently or clamped before the gate: NaN invalid_variance (a NaN
// Imu covariance), NaN max_gap (gap resets stopped), invalid_variance 0 or -1 (clamped to 1e-9).
TEST(SettingsConsistency, TheGateRefusesWhatWasStoredOrClampedSilently) {
  for (const char* value : {"nan", "0", "-1", "inf"})
    EXPECT_NE(vg::checkSettingValue("invalid_variance", value).find("invalid_variance must be in (0, 1000000]"),
              std::string::npos)
        << value;
  EXPECT_EQ(vg::checkSettingValue("invalid_variance", "1e-9"), "");
  for (const char* name : {"max_gap", "min_dt", "max_rate_dps"})
    EXPECT_NE(vg::checkSettingValue(name, "nan").find(name), std::string::npos) << name;
  EXPECT_NE(vg::checkSettingValue("mono16_bit_depth", "5")
                .find("must be 0 (each frame scaled by its own largest value) or in [8, 16], got 5"),
            std::string::npos);
  EXPECT_NE(vg::checkSettingValue("queue_size", "0").find("queue_size must be in [1, 1000]"), std::string::npos);
}

TEST(SettingsConsistency, MarkerBlocksAreReplacedInPlace) {
  const st::GeneratedPart part{"x.md", "<!-- a:begin -->", "<!-- a:end -->", "new\n"};
  std::string out, why;
  ASSERT_TRUE(st::applyPart("head\n<!-- a:begin -->\nold 1\nold 2\n<!-- a:end -->\ntail\n", part, &out, &why));
  EXPECT_EQ(out, "head\n<!-- a:begin -->\nnew\n<!-- a:end -->\ntail\n");
  ASSERT_TRUE(st::applyPart("<!-- a:begin -->\n<!-- a:end -->\n", part, &out, &why));
  EXPECT_EQ(out, "<!-- a:begin -->\nnew\n<!-- a:end -->\n");
  EXPECT_FALSE(st::applyPart("no markers\n", part, &out, &why));
  EXPECT_NE(why.find("x.md"), std::string::npos);
  EXPECT_FALSE(st::applyPart("<!-- a:end -->\n<!-- a:begin -->\n", part, &out, &why));
  EXPECT_FALSE(st::applyPart("<!-- a:begin --> <!-- a:end -->\n", part, &out, &why));
}
