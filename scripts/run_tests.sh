#!/usr/bin/env bash
# Builds and runs every test (gtest unit tests, rostests, launch-file checks) in the catkin
# workspace, then prints one line per failure or skip and, last, "N passed, N failed, N skipped".
set -euo pipefail
source "$(dirname "$0")/env.sh"
log="${WS}/test.log"
results="${WS}/build/test_results"
rm -rf "${results}"
echo "[test] building and running all tests (full log: ${log})"
set +e
(
  cd "${WS}"
  source_ws
  # ROS tests start their own master on a private port so that parallel runs cannot collide.
  export ROS_MASTER_URI="http://localhost:$((20000 + RANDOM % 20000))"
  export ROS_LOG_DIR="${WS}/ros_log"
  catkin_make run_tests -j"$(nproc)"
) >"${log}" 2>&1
status=$?
set -e
if [[ ! -d ${results} ]]; then
  tail -n 60 "${log}"
  echo "[test] no test results were written (build failed?)"
  echo "0 passed, 1 failed, 0 skipped"
  exit 1
fi
if ((status != 0)); then
  grep -n -E "error|Error|FAILED" "${log}" | head -n 30 || true
  tail -n 30 "${log}"
  echo "[test] catkin_make run_tests exited with ${status}"
fi
# The count line comes last, whatever happened above.
/usr/bin/python3 "${REPO_DIR}/scripts/summarize_tests.py" "${results}" || exit 1
exit "${status}"
