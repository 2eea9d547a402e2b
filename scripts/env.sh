# Sourced by the Makefile's scripts: paths of the catkin workspace for the chosen CUDA setting.
# ROS's Python tools need Debian's python3, not a pyenv one earlier in PATH.
export PATH="/usr/bin:/bin:$PATH"
REPO_DIR="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
CUDA_MODE="${CUDA:-AUTO}"
CUDA_MODE="${CUDA_MODE^^}"
# A dot-folder: ROS crawls packages through the workspace link back into the repo and would loop
# through any visible workspace under build/; folders starting with "." are skipped.
WS="${VG_WS:-${REPO_DIR}/build/.ws-${CUDA_MODE,,}}"
DATA_DIR="${VISUAL_GYRO_DATA:-$(cd "$REPO_DIR/.." && pwd)/shared/data}"
BIN="${WS}/devel/lib/visual_gyro"
source_ws() {
  # catkin's setup script reads unset variables; keep it out of `set -u`.
  set +u
  # shellcheck disable=SC1091
  source "${WS}/devel/setup.bash"
  set -u
}
