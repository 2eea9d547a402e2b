# Sourced by the Makefile's scripts: paths of the catkin workspace for the chosen CUDA setting.
# ROS's Python tools need Debian's python3, not a pyenv one earlier in PATH.
export PATH="/usr/bin:/bin:$PATH"
REPO_DIR="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
CUDA_MODE="${CUDA:-AUTO}"
CUDA_MODE="${CUDA_MODE^^}"
# The workspace's src/visual_gyro is a shadow folder (see shadow_package_dir), never a link to the
# whole repository: that would hold build/ and so the workspace itself, and `find -L` (rosrun) or a
# package crawl would loop through it.
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

shadow_package_dir() {
  # ${WS}/src/visual_gyro: one symbolic link per visible top-level entry of the repository except
  # the build and output folders, rebuilt on every build (entries added or removed are picked up).
  local pkg="${WS}/src/visual_gyro" entry name
  [[ -L ${pkg} ]] && rm -f "${pkg}"
  mkdir -p "${pkg}"
  find "${pkg}" -mindepth 1 -maxdepth 1 -type l -delete
  for entry in "${REPO_DIR}"/*; do
    [[ -e ${entry} ]] || continue
    name=$(basename "${entry}")
    case "${name}" in build | out) continue ;; esac
    ln -s "${entry}" "${pkg}/${name}"
  done
}
