#!/usr/bin/env bash
# The visual gyroscope through ROS, headless: starts a private ROS master on a free port, converts
# the default rendered sequence (render_sequence --preset drive) or $DATA (KITTI or EuRoC layout)
# to a bag, replays it frame by frame through the visual_gyro node (play_frames waits for the
# node's answer to each frame, so nothing is dropped however slow the machine), records ~rotation
# and ~imu with `rosbag record`, and prints the summary and, last, one JSON line (evaluate's keys plus
# imu_published and latency_ms) computed from what the node published against the bag's ground truth.
#
# Environment: DATA (sequence folder; default: rendered drive), METHOD (vote or paper; default vote),
# BACKEND (auto, cpu, cuda; default auto), TRANSPORT (raw, or compressed: the bag holds JPEG images,
# quality 90, that the node decodes), PARAMS (more node parameters, "name=value ..."), VG_WS / CUDA
# (workspace, see env.sh), ROS_DEMO_OUT (work folder; default out/ros_demo).
set -euo pipefail
source "$(dirname "$0")/env.sh"

METHOD="${METHOD:-vote}"
BACKEND="${BACKEND:-auto}"
TRANSPORT="${TRANSPORT:-raw}"
OUT_DIR="${ROS_DEMO_OUT:-${REPO_DIR}/out/ros_demo}"
NS=/visual_gyro
log() { echo "[ros-demo] $*" >&2; }

case "${METHOD}" in
  vote | paper) ;;
  *)
    log "METHOD=${METHOD}: the ROS node runs the estimator methods vote and paper; the OpenCV/OpenGV"
    log "baselines run only in the evaluation command (make eval DATA=<folder> METHOD=${METHOD})."
    exit 2
    ;;
esac
case "${TRANSPORT}" in
  raw | compressed) ;;
  *) log "TRANSPORT=${TRANSPORT}: raw or compressed"; exit 2 ;;
esac
source "$(dirname "$0")/ros_common.sh"
require_built visual_gyro_node make_bag play_frames summarize_outputs render_sequence
source_ws
mkdir -p "${OUT_DIR}"

# --- the sequence and its bag ---
prepare_sequence "${OUT_DIR}"
BAG="${OUT_DIR}/${NAME}.bag"
OUTPUTS="${OUT_DIR}/${NAME}_outputs.bag"
bag_args=()
[[ ${TRANSPORT} == compressed ]] && bag_args+=(--compressed jpeg)
log "converting ${SEQ_DIR} to ${BAG}"
"${BIN}/make_bag" "${SEQ_DIR}" "${BAG}" "${bag_args[@]}" >&2

# --- a private master; everything started in the background is stopped on exit ---
start_private_master "${OUT_DIR}"

# --- the node (parameters from config/visual_gyro.yaml) and the recorder ---
rosparam load "${REPO_DIR}/config/visual_gyro.yaml" "${NS}"
rosparam set "${NS}/method" "${METHOD}"
rosparam set "${NS}/backend" "${BACKEND}"
rosparam set "${NS}/image_transport" "${TRANSPORT}"
for assignment in ${PARAMS:-}; do
  rosparam set "${NS}/${assignment%%=*}" "${assignment#*=}"
done
run_background "${OUT_DIR}/node.log" \
  "${BIN}/visual_gyro_node" __name:=visual_gyro image:=/camera/image_raw ground_truth:=/ground_truth/pose
rm -f "${OUTPUTS}" "${OUTPUTS}.active"
# The recorder binary itself (not the `rosbag record` Python wrapper, whose SIGINT forwarding fails
# in a background job) so that waiting for its PID means the bag is closed.
record_cmd=(rosbag record)
[[ -x /usr/lib/rosbag/record ]] && record_cmd=(/usr/lib/rosbag/record)
run_background "${OUT_DIR}/record.log" \
  "${record_cmd[@]}" -O "${OUTPUTS}" "${NS}/rotation" "${NS}/imu" __name:=visual_gyro_recorder
recorder=${LAST_PID}

log "replaying ${NAME} frame by frame through the visual_gyro node (method ${METHOD}, backend ${BACKEND}, ${TRANSPORT} images)"
if ! "${BIN}/play_frames" "${BAG}" --ns "${NS}" --timeout 60 --wait-for "${NS}/rotation" --wait-for "${NS}/imu" \
  >"${OUT_DIR}/play.log" 2>&1; then
  log "replay failed:"
  tail -5 "${OUT_DIR}/play.log" >&2
  log "node log:"
  tail -20 "${OUT_DIR}/node.log" >&2
  exit 1
fi
grep -h "play_frames: published" "${OUT_DIR}/play.log" >&2 || true

# Stop the recorder (SIGINT: it closes the bag) before reading what it wrote.
sleep 0.5
kill -INT "${recorder}"
for _ in $(seq 100); do kill -0 "${recorder}" 2>/dev/null || break; sleep 0.1; done
for _ in $(seq 100); do [[ -f "${OUTPUTS}" && ! -e "${OUTPUTS}.active" ]] && break; sleep 0.1; done
[[ -f "${OUTPUTS}" ]] || { log "rosbag record wrote no ${OUTPUTS}:"; tail -5 "${OUT_DIR}/record.log" >&2; exit 1; }

"${BIN}/summarize_outputs" "${BAG}" "${OUTPUTS}" --ns "${NS}" --dataset "${NAME}"
