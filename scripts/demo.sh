#!/usr/bin/env bash
# make demo: renders the default synthetic sequence (or takes DATA=<folder>) and runs the visual
# gyroscope on it, printing a summary and, last, one JSON line.
set -euo pipefail
source "$(dirname "$0")/env.sh"
method="${METHOD:-vote}"
data="${DATA:-}"
if [[ -z ${data} ]]; then
  data="${REPO_DIR}/out/demo/drive"
  if [[ ! -f ${data}/poses.txt ]]; then
    echo "[demo] rendering the default synthetic sequence (preset drive) into ${data}"
    "${BIN}/render_sequence" --preset drive --out "${data}"
  fi
fi
[[ -d ${data} ]] || { echo "[demo] no such folder: ${data}" >&2; exit 2; }
echo "[demo] running visual_gyro (method ${method}) on ${data}"
"${BIN}/evaluate" "${data}" --method "${method}"
