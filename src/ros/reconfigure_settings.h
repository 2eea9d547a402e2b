// The nodelet's live settings (dynamic_reconfigure's VisualGyroConfig, generated from
// cfg/VisualGyro.cfg, itself generated from the settings tables): the gate a change goes through,
// the pipeline settings made from them, and the ranges shown to GUIs.
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

/// The gate of a live change: every parameter of *config that differs from `in_force` goes
/// through checkSettingValue (node_settings.h); a refused one gets its value in `in_force` back,
/// so that *config holds the values in force. Returns the refusals, each "name old -> new: why"
/// (why names the setting), joined with "; "; "" when none.
std::string refuseInvalid(const Config& in_force, Config* config);

/// The pipeline settings of `config`: every entry the settings table knows (findSetting) applied by
/// name through applySetting, with the node's ~backend request; the entries it does not know are
/// the node's own (max_gap, stamp_at_midpoint, ...). "" or why the settings are unusable: the
/// first entry that does not parse or is out of range, else validateVisualGyroSettings' answer.
std::string pipelineSettings(const Config& config, const std::string& backend, VisualGyroSettings* settings);

/// The ranges of the numeric live settings as configurations, for GUIs (the server's published
/// description): the cfg gives none, so that the server clamps nothing and the gate sees every
/// value. Settings without a range keep the generated limits.
void ranges(Config* min, Config* max);

}  // namespace reconfigure_settings
}  // namespace visual_gyro
