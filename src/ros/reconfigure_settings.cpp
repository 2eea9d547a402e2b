#include "reconfigure_settings.h"

#include <boost/any.hpp>
#include <dynamic_reconfigure/Config.h>

#include "node_settings.h"

namespace visual_gyro {
namespace reconfigure_settings {

namespace {

/// The value as text: numbers as the shortest exact decimal (NaN as "nan"), bools as true/false.
std::string valueText(const Config::AbstractParamDescription& description, const Config& config) {
  boost::any value;
  description.getValue(config, value);
  if (description.type == "double") return SettingSpec::formatNumber(boost::any_cast<double>(value));
  if (description.type == "int") return std::to_string(boost::any_cast<int>(value));
  if (description.type == "bool") return boost::any_cast<bool>(value) ? "true" : "false";
  return boost::any_cast<std::string>(value);
}

/// Sets the parameter of `description` in *config to `value` (a number: the parameter is int or double).
void setNumber(const Config::AbstractParamDescription& description, double value, Config* config) {
  dynamic_reconfigure::Config message;
  if (description.type == "double") {
    dynamic_reconfigure::DoubleParameter p;
    p.name = description.name;
    p.value = value;
    message.doubles.push_back(p);
  } else {
    dynamic_reconfigure::IntParameter p;
    p.name = description.name;
    p.value = static_cast<int>(value);
    message.ints.push_back(p);
  }
  description.fromMessage(message, *config);
}

}  // namespace

std::vector<std::pair<std::string, std::string>> entries(const Config& config) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& description : Config::__getParamDescriptions__())
    out.emplace_back(description->name, valueText(*description, config));
  return out;
}

std::string refuseInvalid(const Config& in_force, Config* config) {
  std::vector<std::string> refused;
  for (const auto& description : Config::__getParamDescriptions__()) {
    const std::string old_value = valueText(*description, in_force);
    const std::string new_value = valueText(*description, *config);
    if (old_value == new_value) continue;
    const std::string why = checkSettingValue(description->name, new_value);
    if (why.empty()) continue;
    refused.push_back(description->name + " " + old_value + " -> " + new_value + ": " + why);
    // The value in force goes back through the config message: the descriptions have no setter.
    dynamic_reconfigure::Config message;
    description->toMessage(message, in_force);
    description->fromMessage(message, *config);
  }
  return SettingSpec::joined(refused, "; ");
}

std::string pipelineSettings(const Config& config, const std::string& backend, VisualGyroSettings* settings) {
  *settings = VisualGyroSettings();
  std::string problem = applySetting(settings, "backend", backend);
  for (const auto& entry : entries(config)) {
    if (findSetting(entry.first) == nullptr) continue;  // a node setting
    const std::string why = applySetting(settings, entry.first, entry.second);
    if (problem.empty()) problem = why;
  }
  return problem.empty() ? validateVisualGyroSettings(*settings) : problem;
}

void ranges(Config* min, Config* max) {
  *min = Config::__getMin__();
  *max = Config::__getMax__();
  for (const auto& description : Config::__getParamDescriptions__()) {
    if (description->type != "double" && description->type != "int") continue;
    const SettingSpec* spec = findAnySetting(description->name).spec;
    if (spec == nullptr) continue;
    setNumber(*description, spec->min, min);
    setNumber(*description, spec->max, max);
  }
}

}  // namespace reconfigure_settings
}  // namespace visual_gyro
