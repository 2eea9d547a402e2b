#!/usr/bin/env bash
# make rviz-shot: replays a sequence through launch/replay.launch with rviz:=true and the real
# `rosbag play`, under a private Xvfb display and a private ROS master, takes a screenshot of the
# whole screen (imagemagick's `import`) once the bag has played, writes it to out/rviz/replay.png
# and checks it (scripts/check_rviz_shot.py: estimate and ground-truth colours in the 3D view, no
# warning or error colour in the Displays panel).
#
# Environment: DATA (sequence folder, KITTI or EuRoC layout; default: a rendered drive), FRAMES
# (at most this many frames; default: all, 60 for the rendered drive), RATE (playback rate,
# default 1), RVIZ_SHOT_OUT (folder; default out/rviz), VG_WS / CUDA (workspace, see env.sh).
# The bag holds raw images: rviz's image display cannot show compressed ones without
# image_transport's compressed plugin, which Debian does not have.
set -euo pipefail
source "$(dirname "$0")/env.sh"

OUT_DIR="${RVIZ_SHOT_OUT:-${REPO_DIR}/out/rviz}"
FRAMES="${FRAMES:-0}"
RATE="${RATE:-1}"
log() { echo "[rviz-shot] $*" >&2; }

for tool in rviz Xvfb import roslaunch; do
  command -v "${tool}" >/dev/null || { log "missing ${tool}: run scripts/install_deps.sh (make deps)"; exit 1; }
done
source "$(dirname "$0")/ros_common.sh"
require_built make_bag render_sequence
source_ws
mkdir -p "${OUT_DIR}"

# --- the bag ---
prepare_sequence "${OUT_DIR}" "$((FRAMES > 0 ? FRAMES : 60))"
BAG="${OUT_DIR}/${NAME}.bag"
bag_args=()
((FRAMES > 0)) && bag_args+=(--max-frames "${FRAMES}")
"${BIN}/make_bag" "${SEQ_DIR}" "${BAG}" "${bag_args[@]}" | tee "${OUT_DIR}/make_bag.log" >&2
# "stamps A .. B s": B is the last image's stamp.
LAST_STAMP="$(sed -n 's/.*stamps [0-9.]* \.\. \([0-9.]*\) s.*/\1/p' "${OUT_DIR}/make_bag.log")"
[[ -n ${LAST_STAMP} ]] || { log "could not read the last stamp from make_bag's output"; exit 1; }

# --- a private display and master; everything started in the background is stopped on exit ---
display=""
for n in $(seq 91 250); do
  if [[ ! -e /tmp/.X11-unix/X${n} && ! -e /tmp/.X${n}-lock ]]; then display=${n}; break; fi
done
[[ -n ${display} ]] || { log "no free X display number"; exit 1; }
run_background "${OUT_DIR}/xvfb.log" Xvfb ":${display}" -screen 0 1400x900x24 -nolisten tcp
for _ in $(seq 100); do [[ -e /tmp/.X11-unix/X${display} ]] && break; sleep 0.1; done
[[ -e /tmp/.X11-unix/X${display} ]] || { log "Xvfb did not start:"; cat "${OUT_DIR}/xvfb.log" >&2; exit 1; }
export DISPLAY=":${display}"
# rviz's settings (last config, window state) go to a private home, never the user's.
export HOME="${OUT_DIR}/home"
mkdir -p "${HOME}"

start_private_master "${OUT_DIR}"

log "replaying ${NAME} through replay.launch with rviz on display :${display}"
# Paused until rviz and the node have subscribed (rviz takes seconds to start with software
# OpenGL); kept alive after the end so that rviz still shows everything for the screenshot.
run_background "${OUT_DIR}/roslaunch.log" roslaunch visual_gyro replay.launch "bag:=${BAG}" rviz:=true \
  "rate:=${RATE}" delay:=0 player_args:="--pause --keep-alive"
input_topic=/camera/camera_info
if ! /usr/bin/python3 "${REPO_DIR}/scripts/replay_control.py" --last-stamp "${LAST_STAMP}" \
  --subscribed /camera/visual_gyro/yaw_plot --subscribed "${input_topic}" --settle 3 --timeout 240 \
  2>"${OUT_DIR}/replay_control.log"; then
  cat "${OUT_DIR}/replay_control.log" >&2
  log "roslaunch log:"
  tail -30 "${OUT_DIR}/roslaunch.log" >&2
  exit 1
fi
cat "${OUT_DIR}/replay_control.log" >&2
import -window root "${OUT_DIR}/replay.png"
log "screenshot: ${OUT_DIR}/replay.png"
/usr/bin/python3 "${REPO_DIR}/scripts/check_rviz_shot.py" "${OUT_DIR}/replay.png"
