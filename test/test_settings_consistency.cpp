// One source of truth for the settings: the settings table (visualGyroSettingFields: name, type,
// default, range, choices) against cfg/VisualGyro.cfg, config/visual_gyro.yaml, the README and the
// validation. Fails when any copy drifts, or when validation accepts other values than the ranges.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "visual_gyro/visual_gyro.h"

namespace fs = std::filesystem;
namespace vg = visual_gyro;

namespace {

fs::path repo() { return fs::path(__FILE__).parent_path().parent_path(); }

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
  std::string min_text, max_text;  ///< empty for bool and str
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

std::map<std::string, CfgEntry> cfgEntries() {
  std::map<std::string, CfgEntry> out;
  const std::string text = readAll(repo() / "cfg" / "VisualGyro.cfg");
  const auto enums = cfgEnums(text);
  // gen.add("name", type, level, "doc", default[, min, max][, edit_method=enum])
  const std::regex add(
      R"re(gen\.add\("(\w+)",\s*(\w+),\s*\d+,\s*"[^"]*",\s*("[^"]*"|[^,\s)]+)(?:,\s*([^,\s)=]+),\s*([^,\s)=]+))?(?:,\s*edit_method=(\w+))?\))re");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), add); it != std::sregex_iterator(); ++it) {
    CfgEntry e;
    e.type = (*it)[2];
    e.default_text = (*it)[3];
    e.min_text = (*it)[4];
    e.max_text = (*it)[5];
    const std::string edit = (*it)[6];
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
  const std::regex entry(R"re(^(\w+):\s*("[^"]*"|[^#\s]+))re");
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
  }
  return "?";
}

// Settings read once at start (not live): in the yaml, not in the .cfg.
bool startOnly(const std::string& name) { return name == "backend"; }

}  // namespace

TEST(SettingsConsistency, TableCfgYamlAndReadmeAgree) {
  const auto cfg = cfgEntries();
  const auto yaml = yamlValues();
  const std::string readme = readAll(repo() / "README.md");
  const vg::VisualGyroSettings defaults;
  ASSERT_GT(cfg.size(), 30u) << "the .cfg was not parsed";
  ASSERT_GT(vg::visualGyroSettingFields().size(), 30u);
  for (const auto& field : vg::visualGyroSettingFields()) {
    SCOPED_TRACE(field.name);
    const std::string value = field.text(defaults);
    EXPECT_NE(readme.find("`" + field.name + "`"), std::string::npos) << "not in the README";
    const auto y = yaml.find(field.name);
    ASSERT_NE(y, yaml.end()) << "not in config/visual_gyro.yaml";
    EXPECT_EQ(normalised(y->second), normalised(value)) << "yaml " << y->second << ", C++ default " << value;
    const auto c = cfg.find(field.name);
    if (startOnly(field.name)) {
      EXPECT_EQ(c, cfg.end()) << "read once at start: not live-tunable";
      continue;
    }
    ASSERT_NE(c, cfg.end()) << "not in cfg/VisualGyro.cfg";
    EXPECT_EQ(c->second.type, cfgType(field.type));
    EXPECT_EQ(normalised(c->second.default_text), normalised(value))
        << ".cfg default " << c->second.default_text << ", C++ default " << value;
    if (field.type == vg::SettingType::kInt || field.type == vg::SettingType::kDouble) {
      EXPECT_EQ(normalised(c->second.min_text), normalised(vg::SettingField<vg::VisualGyroSettings>::formatNumber(field.min)))
          << ".cfg min " << c->second.min_text << ", table min " << field.min;
      EXPECT_EQ(normalised(c->second.max_text), normalised(vg::SettingField<vg::VisualGyroSettings>::formatNumber(field.max)))
          << ".cfg max " << c->second.max_text << ", table max " << field.max;
    }
    if (!field.choices.empty()) EXPECT_EQ(c->second.choices, field.choices) << "enum constants differ";
  }
}

TEST(SettingsConsistency, ReadmeTableIsTheTablesOutput) {
  const std::string readme = readAll(repo() / "README.md");
  const std::string table = vg::settingsMarkdownTable();
  EXPECT_NE(readme.find(table), std::string::npos)
      << "the README's settings table differs from `evaluate --settings-table`:\n" << table;
}

TEST(SettingsConsistency, NodeSettingsInTheCfgAreInTheYamlAndReadme) {
  const auto yaml = yamlValues();
  const std::string readme = readAll(repo() / "README.md");
  for (const auto& entry : cfgEntries()) {
    if (vg::findSetting(entry.first) != nullptr) continue;  // checked against the table above
    SCOPED_TRACE(entry.first);
    const auto y = yaml.find(entry.first);
    ASSERT_NE(y, yaml.end()) << "in the .cfg but not in config/visual_gyro.yaml";
    EXPECT_EQ(normalised(entry.second.default_text), normalised(y->second));
    EXPECT_NE(readme.find("`" + entry.first + "`"), std::string::npos) << "not in the README";
  }
  ASSERT_TRUE(yaml.count("mono16_bit_depth"));
  EXPECT_EQ(yaml.at("mono16_bit_depth"), "0");
}

// The cfg accepts exactly what validation accepts: both ends of every range are valid (with every
// other setting at its default), and the first value beyond each end is refused, naming the setting.
TEST(SettingsConsistency, ValidationAcceptsExactlyTheRanges) {
  for (const auto& field : vg::visualGyroSettingFields()) {
    if (field.type != vg::SettingType::kInt && field.type != vg::SettingType::kDouble) continue;
    SCOPED_TRACE(field.name);
    const double step = field.type == vg::SettingType::kInt ? 1.0 : std::max(1e-9, 1e-6 * std::abs(field.max - field.min));
    auto text = [&](double v) {
      return field.type == vg::SettingType::kInt ? std::to_string(static_cast<long long>(v))
                                                 : vg::SettingField<vg::VisualGyroSettings>::formatNumber(v);
    };
    for (const double inside : {field.min, field.max}) {
      vg::VisualGyroSettings s;
      ASSERT_EQ(vg::applySetting(&s, field.name, text(inside)), "") << text(inside);
      EXPECT_EQ(vg::validateVisualGyroSettings(s), "") << field.name << " = " << text(inside);
    }
    for (const double outside : {field.min - step, field.max + step}) {
      if (field.name == "seed" && outside < 0) continue;  // unsigned: not representable
      vg::VisualGyroSettings s;
      const std::string why = vg::applySetting(&s, field.name, text(outside));
      EXPECT_NE(why.find(field.name), std::string::npos) << text(outside) << " accepted: '" << why << "'";
      EXPECT_EQ(vg::validateVisualGyroSettings(s), "") << "a refused value changed the settings";
    }
  }
  // Text that is no value of its type, and unknown names, are refused too.
  vg::VisualGyroSettings s;
  EXPECT_NE(vg::applySetting(&s, "hypotheses", "many"), "");
  EXPECT_NE(vg::applySetting(&s, "cross_check", "perhaps"), "");
  EXPECT_NE(vg::applySetting(&s, "matching", "sideways").find("guided, global"), std::string::npos);
  EXPECT_NE(vg::applySetting(&s, "no_such_setting", "1").find("unknown setting"), std::string::npos);
}
