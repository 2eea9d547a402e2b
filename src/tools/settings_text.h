// The files made from the settings tables (the pipeline's, visualGyroSettingFields(), and the
// node's, nodeSettingFields()): cfg/VisualGyro.cfg, config/visual_gyro.yaml, and the settings
// tables between markers in README.md and doc/ros.md. `settings_files` writes them
// (`make settings-files`); test_settings_consistency fails when a committed copy differs.
#pragma once

#include <string>
#include <vector>

namespace visual_gyro {
namespace settings_text {

/// The command that regenerates every generated file (printed when one differs).
constexpr const char* kRegenerateCommand = "make settings-files";

/// cfg/VisualGyro.cfg: every live setting of both tables, by tier, as a dynamic_reconfigure
/// script without min and max (the server would clamp to them before the node could refuse).
std::string cfgFile();

/// config/visual_gyro.yaml: every setting of both tables with its default, by tier, each under a
/// comment with its meaning, accepted values and whether it is live.
std::string yamlFile();

/// The user-tier settings of both tables as a Markdown table (setting, default, accepted,
/// meaning): README.md between its user-settings markers.
std::string readmeUserSettings();

/// Every pipeline setting, one table per tier: doc/ros.md between its settings-table markers.
std::string rosSettingsTable();

/// Every node setting, one table per tier: doc/ros.md between its node-settings markers.
std::string rosNodeSettings();

/// One generated part of a file: the whole file (begin and end empty) or the lines between the
/// line holding `begin` and the line holding `end`.
struct GeneratedPart {
  std::string path;  ///< relative to the repository root
  std::string begin, end;
  std::string text;  ///< what the whole file or the block holds
};

/// Every generated part, in a fixed order.
std::vector<GeneratedPart> generatedParts();

/// `file` with `part` in it: the whole text, or the lines between the markers replaced. False (and
/// `why`) when a marker is missing or the end marker comes first.
bool applyPart(const std::string& file, const GeneratedPart& part, std::string* out, std::string* why);

}  // namespace settings_text
}  // namespace visual_gyro
