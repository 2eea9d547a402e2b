#!/usr/bin/env bash
# `make calibrate DATA=<EuRoC folder | file.bag> [IMAGE_TOPIC=...] [IMU_TOPIC=...]`: the camera-IMU
# alignment (calibrate_imu) of one recording: time offset, the camera's rotation in the IMU frame,
# the gyro's bias. Prints a summary, what to paste (the node's time_offset, a static tf, the bias)
# and, last, one JSON line. Extra arguments are passed to calibrate_imu (e.g. --scale).
set -euo pipefail
source "$(dirname "$0")/env.sh"
DATA="${DATA:-}"
if [[ -z ${DATA} ]]; then
  echo "usage: make calibrate DATA=<EuRoC folder with cam0/ and imu0/ | file.bag> [IMAGE_TOPIC=/cam0/image_raw IMU_TOPIC=/imu0]" >&2
  exit 2
fi
if [[ ! -x ${BIN}/calibrate_imu ]]; then
  echo "[calibrate] ${BIN}/calibrate_imu not built (run make build)" >&2
  exit 1
fi
args=("${DATA}" --quiet)
[[ -n ${IMAGE_TOPIC:-} ]] && args+=(--image-topic "${IMAGE_TOPIC}")
[[ -n ${IMU_TOPIC:-} ]] && args+=(--imu-topic "${IMU_TOPIC}")
# A bag is read through rosbag's libraries: the workspace's environment.
source_ws
exec "${BIN}/calibrate_imu" "${args[@]}" "$@"
