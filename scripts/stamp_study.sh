#!/usr/bin/env bash
# Which stamp should the outputs carry? Replays a sequence with ground truth ($DATA, default
# ../shared/data/kitti_turn) through the node twice (scripts/ros_demo.sh: current-image stamps, then
# midpoint stamps), integrates the recorded ~imu the way a fusion filter does (each rate held from
# its stamp to the next message's; integrate_imu) and prints the orientation error over time for
# both, side by side, then one summary line each.
set -euo pipefail
source "$(dirname "$0")/env.sh"
DATA="${DATA:-${DATA_DIR}/kitti_turn}"
OUT_DIR="${STAMP_STUDY_OUT:-${REPO_DIR}/out/stamp_study}"
mkdir -p "${OUT_DIR}"
[[ -d ${DATA} ]] || { echo "[stamp-study] no sequence at ${DATA}" >&2; exit 2; }
NAME="$(basename "$(cd "${DATA}" && pwd)")"
for stamp in current midpoint; do
  midpoint=false
  [[ ${stamp} == midpoint ]] && midpoint=true
  DATA="${DATA}" ROS_DEMO_OUT="${OUT_DIR}/${stamp}" PARAMS="stamp_at_midpoint=${midpoint}" \
    "${REPO_DIR}/scripts/ros_demo.sh" >"${OUT_DIR}/${stamp}.json" 2>"${OUT_DIR}/${stamp}.log" ||
    { tail -20 "${OUT_DIR}/${stamp}.log" >&2; exit 1; }
  "${BIN}/integrate_imu" "${OUT_DIR}/${stamp}/${NAME}.bag" "${OUT_DIR}/${stamp}/${NAME}_outputs.bag" \
    --print-every 0.5 >"${OUT_DIR}/${stamp}.txt"
done
echo "orientation error [deg] of the ~imu rates integrated from each stamp, ${NAME}"
echo "time_s current_image midpoint"
paste -d' ' <(sed '1d;$d' "${OUT_DIR}/current.txt") <(sed '1d;$d' "${OUT_DIR}/midpoint.txt" | cut -d' ' -f2)
for stamp in current midpoint; do echo "${stamp}: $(tail -1 "${OUT_DIR}/${stamp}.txt")"; done
