#!/usr/bin/env bash
# `make eval DATA=<folder> METHOD=<name>[,<name>...]`: the evaluation command alone on one
# sequence folder (KITTI or EuRoC layout); its last output line is the JSON object of the last
# method. Extra arguments are passed to evaluate (e.g. --csv per_frame.csv).
set -euo pipefail
source "$(dirname "$0")/env.sh"
DATA="${DATA:-}"
METHOD="${METHOD:-vote}"
if [[ -z ${DATA} ]]; then
  echo "usage: make eval DATA=<sequence folder> [METHOD=vote|paper|essential5|fundamental8|...]" >&2
  exit 2
fi
if [[ ! -x ${BIN}/evaluate ]]; then
  echo "[eval] ${BIN}/evaluate not built (run make build)" >&2
  exit 1
fi
exec "${BIN}/evaluate" "${DATA}" --method "${METHOD}" --quiet "$@"
