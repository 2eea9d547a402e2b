# Sourced by the scripts that run the node under a private ROS master (ros_demo.sh, rviz_shot.sh),
# after env.sh and after defining log(): the sequence to replay, the master, background processes
# stopped on exit.

# Every tool named must be built in ${BIN}.
require_built() {
  local tool
  for tool in "$@"; do
    [[ -x "${BIN}/${tool}" ]] || { log "missing ${BIN}/${tool}: build first (make build, or scripts/build.sh)"; exit 1; }
  done
}

# Sets SEQ_DIR and NAME: $DATA (a KITTI or EuRoC folder) when set, else the rendered drive
# (render_sequence --preset drive, FRAMES frames when given) written into the folder $1.
prepare_sequence() {
  local out_dir="$1" frames="${2:-}"
  if [[ -n "${DATA:-}" ]]; then
    [[ -d "${DATA}" ]] || { log "DATA=${DATA} is not a folder"; exit 2; }
    SEQ_DIR="$(cd "${DATA}" && pwd)"
    NAME="$(basename "${SEQ_DIR}")"
    return
  fi
  NAME=rendered_drive
  SEQ_DIR="${out_dir}/${NAME}"
  log "rendering the default sequence (preset drive) into ${SEQ_DIR}"
  rm -rf "${SEQ_DIR}"
  local args=(--preset drive --out "${SEQ_DIR}")
  [[ -n ${frames} ]] && args+=(--frames "${frames}")
  "${BIN}/render_sequence" "${args[@]}" >"${out_dir}/render.log" 2>&1 || { cat "${out_dir}/render.log" >&2; exit 1; }
}

# Processes started with run_background, stopped (SIGINT, then SIGKILL after 10 s) in reverse
# order on exit.
pids=()
stop_background() {
  local i pid
  for ((i = ${#pids[@]} - 1; i >= 0; i--)); do kill -INT "${pids[i]}" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do
    for _ in $(seq 100); do kill -0 "${pid}" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "${pid}" 2>/dev/null || true
  done
}
trap stop_background EXIT
trap 'exit 130' INT TERM

# Runs "$@" in the background with its output in the file $1 (shifted off); its PID is LAST_PID.
run_background() {
  local log_file="$1"
  shift
  "$@" >"${log_file}" 2>&1 &
  LAST_PID=$!
  pids+=("${LAST_PID}")
}

# A private ROS master on a free port, its logs and ROS_HOME under the folder $1; waits until it
# answers.
start_private_master() {
  local out_dir="$1" port
  port="$(/usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
  export ROS_MASTER_URI="http://localhost:${port}" ROS_HOSTNAME=localhost
  export ROS_LOG_DIR="${out_dir}/log" ROS_HOME="${out_dir}/ros_home"
  unset ROS_IP
  mkdir -p "${ROS_LOG_DIR}" "${ROS_HOME}"
  log "starting a ROS master on port ${port}"
  run_background "${out_dir}/roscore.log" roscore -p "${port}"
  for _ in $(seq 150); do
    rostopic list >/dev/null 2>&1 && return 0
    sleep 0.2
  done
  log "the ROS master did not come up:"
  tail -20 "${out_dir}/roscore.log" >&2
  exit 1
}
