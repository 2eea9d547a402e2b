#!/usr/bin/env bash
# Regenerates the files made from the settings tables (cfg/VisualGyro.cfg, config/visual_gyro.yaml
# and the settings blocks of README.md and doc/ros.md) with the settings_files command of the
# built workspace; when the cfg changed, builds again so that dynamic_reconfigure's header follows.
set -euo pipefail
source "$(dirname "$0")/env.sh"
written=$("${BIN}/settings_files" "${REPO_DIR}")
[[ -n ${written} ]] && echo "${written}"
echo "[settings-files] the generated files match the settings tables"
if grep -q "cfg/VisualGyro.cfg" <<<"${written}"; then
  "$(dirname "$0")/build.sh"
fi
