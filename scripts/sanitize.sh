#!/usr/bin/env bash
# `make sanitize`: builds the package in its own workspace (build/.ws-sanitize, CUDA off) with
# AddressSanitizer and UndefinedBehaviorSanitizer (float-cast-overflow included: GCC's "undefined"
# set lacks it), then runs the unit tests, the rostests, and `evaluate` over the shared sequences.
# The malformed inputs kept in test/ (made by the tests themselves) run inside the unit tests.
# Every sanitizer report is written under the workspace and fails the run; the last line is
# "N passed, N failed, N skipped".
set -uo pipefail
export CUDA=OFF
export VG_WS="${VG_WS:-$(cd "$(dirname "$0")/.." && pwd)/build/.ws-sanitize}"
source "$(dirname "$0")/env.sh"

flags="-fsanitize=address,undefined,float-cast-overflow -fno-omit-frame-pointer -fno-sanitize-recover=undefined,float-cast-overflow"
reports="${WS}/sanitizer_reports"
rm -rf "${reports}"
mkdir -p "${reports}"
start=$(date +%s)
# -O1 -g: readable stacks at a fraction of the -O0 run time.
"$(dirname "$0")/build.sh" -DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g" \
  "-DCMAKE_CXX_FLAGS=${flags}" "-DCMAKE_EXE_LINKER_FLAGS=-fsanitize=address,undefined" \
  "-DCMAKE_SHARED_LINKER_FLAGS=-fsanitize=address,undefined" || {
  echo "[sanitize] build failed"
  echo "0 passed, 1 failed, 0 skipped"
  exit 1
}
echo "[sanitize] built in $(($(date +%s) - start)) s"

# ASan/LSan reports go to files (one per process), so that a report in a child process whose output
# a test swallows still fails the run; UBSan writes to stderr whatever log_path says. A distinct
# exit code (86) keeps a sanitizer's exit apart from the commands' own 1 and 2.
# log_exe_name: the report's file name says which program (report.<program>.<pid>).
common="log_path=${reports}/report:log_exe_name=1:exitcode=86"
export ASAN_OPTIONS="${common}:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1"
export UBSAN_OPTIONS="${common}:print_stacktrace=1:halt_on_error=1"
export LSAN_OPTIONS="suppressions=${REPO_DIR}/test/sanitizer/lsan.supp:print_suppressions=0"

# The soak rostest: slower, and without its memory and answer checks (see test/ros/soak.test).
export VISUAL_GYRO_SOAK_ASSERT=false VISUAL_GYRO_SOAK_RATE=10
failed=0
passed=0
skipped=0
add_counts() {  # adds a "N passed, N failed, N skipped" line to the totals
  local line="$1" p f s
  read -r p _ f _ s _ <<<"${line//,/}"
  passed=$((passed + p)); failed=$((failed + f)); skipped=$((skipped + s))
}

log="${WS}/sanitize.log"
: >"${log}"
cd "${WS}"
source_ws
export ROS_MASTER_URI="http://localhost:$((20000 + RANDOM % 20000))"
export ROS_LOG_DIR="${WS}/ros_log"
rm -rf "${WS}/build/test_results"
# Every test executable first, without the preload below.
if ! catkin_make tests -j"$(nproc)" >>"${log}" 2>&1; then
  echo "FAILED  building the tests (see ${log})"
  failed=$((failed + 1))
fi
# Unit tests: instrumented executables, leak detection on. (catkin's run_tests targets succeed
# when tests fail; a failure here is a build failure.)
if ! catkin_make run_tests_visual_gyro_gtest -j"$(nproc)" >>"${log}" 2>&1; then
  echo "FAILED  building or running the unit tests (see ${log})"
  failed=$((failed + 1))
fi
# ROS tests: the nodelet manager and the Python tools are not instrumented, so the ASan runtime
# is preloaded for them (leak checks off there: Python's own allocations are not ours).
if ! LD_PRELOAD="$(gcc -print-file-name=libasan.so)" ASAN_OPTIONS="${common}:detect_leaks=0" \
    catkin_make run_tests_visual_gyro_rostest -j1 >>"${log}" 2>&1; then
  echo "FAILED  building or running the rostests (see ${log})"
  failed=$((failed + 1))
fi
line=$(/usr/bin/python3 "${REPO_DIR}/scripts/summarize_tests.py" "${WS}/build/test_results" | tee -a "${log}" | tail -n 1)
grep -E "^(FAILED|SKIPPED)" "${log}" || true
add_counts "${line}"

# evaluate over every shared sequence (its own methods and a baseline).
if [[ -d ${DATA_DIR} ]]; then
  for folder in "${DATA_DIR}"/*/; do
    [[ -d ${folder} ]] || continue
    if "${BIN}/evaluate" "${folder}" --method vote,paper,essential5 --backend cpu --quiet >>"${log}" 2>&1; then
      passed=$((passed + 1))
    else
      echo "FAILED  evaluate ${folder} (exit $?)"
      failed=$((failed + 1))
    fi
  done
else
  echo "SKIPPED evaluate over the shared sequences: ${DATA_DIR} not found"
  skipped=$((skipped + 1))
fi

# Any sanitizer report fails the run: ASan/LSan write theirs to files; UBSan's go to stderr, so
# the log (tests' and nodes' output) and the ROS logs are searched too.
shopt -s nullglob
report_files=("${reports}"/report*)
if ((${#report_files[@]} > 0)); then
  for f in "${report_files[@]}"; do
    echo "FAILED  sanitizer report ${f}:"
    # The error, the first frames of each stack (access, free, allocation) and the summary: enough
    # to find a race that a later run may not repeat.
    grep -E "ERROR|runtime error|SUMMARY|freed by|allocated by|Thread T|^ *#[0-9] " "${f}" | head -n 60 |
      sed 's/^/        /'
  done
  failed=$((failed + ${#report_files[@]}))
fi
pattern="runtime error:|ERROR: AddressSanitizer|ERROR: LeakSanitizer"
in_logs=$(grep -r -h -E "${pattern}" "${log}" "${WS}/ros_log" 2>/dev/null | sort -u || true)
if [[ -n ${in_logs} ]]; then
  echo "FAILED  sanitizer reports in the logs:"
  echo "${in_logs}" | head -n 20 | sed 's/^/        /'
  failed=$((failed + $(echo "${in_logs}" | wc -l)))
fi
echo "[sanitize] full log: ${log}; took $(($(date +%s) - start)) s"
echo "${passed} passed, ${failed} failed, ${skipped} skipped"
((failed == 0 && passed > 0))
