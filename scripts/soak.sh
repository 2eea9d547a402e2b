#!/usr/bin/env bash
# `make soak MINUTES=N` (default 10): the node under a 30 Hz forwards-and-backwards replay of
# ../shared/data/kitti_turn (rendered frames without it), with memory, descriptors, threads and
# latency sampled every 10 s. Its last line is the JSON summary (see test/ros/soak.cpp).
set -euo pipefail
source "$(dirname "$0")/env.sh"
minutes="${MINUTES:-10}"
result="${WS}/soak.json"
junit="${ROS_HOME:-$HOME/.ros}/test_results/visual_gyro/rosunit-soak.xml"
rm -f "${result}" "${junit}"
cd "${WS}"
source_ws
export ROS_MASTER_URI="http://localhost:$((20000 + RANDOM % 20000))"
export ROS_LOG_DIR="${WS}/ros_log"
catkin_make test_soak -j"$(nproc)" >/dev/null
status=0
rostest --text visual_gyro soak.test minutes:="${minutes}" result_file:="${result}" assert:=true 2>&1 |
  grep -E "^\[soak\]|Failure|Expected|Which is|FAILED" || true
[[ -s ${result} ]] || { echo "[soak] no result written"; exit 1; }
grep -q '"answered_fraction"' "${result}" || status=1
# The checks (growth after the warm-up, descriptors, answers) are the test's; its JUnit file says.
if [[ ! -f ${junit} ]] || grep -q "<failure" "${junit}"; then
  echo "[soak] the checks failed (${junit})"
  status=1
fi
cat "${result}"
exit "${status}"
