// The nodelet's live settings (dynamic_reconfigure's VisualGyroConfig) as name/value pairs, the
// pipeline settings made from them, and the text naming what a change changes.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "visual_gyro/VisualGyroConfig.h"
#include "visual_gyro/visual_gyro.h"

namespace visual_gyro {
namespace reconfigure_settings {

using Config = visual_gyro::VisualGyroConfig;

/// Every parameter of `config`, in the order of cfg/VisualGyro.cfg, as (name, value text); doubles
/// with enough digits to read back the same value, bools as "true"/"false".
std::vector<std::pair<std::string, std::string>> entries(const Config& config);

/// The parameters that differ, as "name old -> new" joined with ", " ("" when none).
std::string describeChange(const Config& before, const Config& after);

/// The pipeline settings of `config`: every entry the settings table knows (findSetting) applied by
/// name through applySetting, with the node's ~backend request; the entries it does not know are
/// the node's own (max_gap, stamp_at_midpoint, ...). "" or why the settings are unusable: the
/// first entry that does not parse or is out of range, else validateVisualGyroSettings' answer.
std::string pipelineSettings(const Config& config, const std::string& backend, VisualGyroSettings* settings);

}  // namespace reconfigure_settings
}  // namespace visual_gyro
