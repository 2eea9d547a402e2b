#include "reconfigure_settings.h"


#include <boost/any.hpp>

namespace visual_gyro {
namespace reconfigure_settings {

namespace {

using Field = SettingField<VisualGyroSettings>;

/// The value as text: numbers as the shortest exact decimal, bools as true/false.
std::string valueText(const Config::AbstractParamDescription& description, const Config& config) {
  boost::any value;
  description.getValue(config, value);
  if (description.type == "double") return Field::formatNumber(boost::any_cast<double>(value));
  if (description.type == "int") return std::to_string(boost::any_cast<int>(value));
  if (description.type == "bool") return boost::any_cast<bool>(value) ? "true" : "false";
  return boost::any_cast<std::string>(value);
}

}  // namespace

std::vector<std::pair<std::string, std::string>> entries(const Config& config) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& description : Config::__getParamDescriptions__())
    out.emplace_back(description->name, valueText(*description, config));
  return out;
}

std::string describeChange(const Config& before, const Config& after) {
  std::string text;
  for (const auto& description : Config::__getParamDescriptions__()) {
    const std::string old_value = valueText(*description, before);
    const std::string new_value = valueText(*description, after);
    if (old_value == new_value) continue;
    if (!text.empty()) text += ", ";
    text += description->name + " " + old_value + " -> " + new_value;
  }
  return text;
}

std::string pipelineSettings(const Config& config, const std::string& backend, VisualGyroSettings* settings) {
  *settings = VisualGyroSettings();
  std::string problem = applySetting(settings, "backend", backend);
  for (const auto& entry : entries(config)) {
    if (findSetting(entry.first) == nullptr) continue;  // a node setting
    const std::string why = applySetting(settings, entry.first, entry.second);
    if (problem.empty()) problem = why;
  }
  settings->run_estimator = true;
  return problem.empty() ? validateVisualGyroSettings(*settings) : problem;
}

}  // namespace reconfigure_settings
}  // namespace visual_gyro
