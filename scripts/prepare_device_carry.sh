#!/usr/bin/env bash
# Fills .device_carry/ (git-ignored) with what scripts/gpu_bench.sh needs on a machine with a GPU
# but without the data, ROS or Eigen; copy it there with the working tree:
#   bearings/<sequence>.txt  matched bearings (+ dt, true rotation) of the shared sequences present,
#                            exported by `evaluate --export-bearings` (needs `make build` first);
#   eigen3/Eigen/            Eigen's headers, for cuda_estimator_check.
# About 32 MB in all (25 MB of bearings for the four shared sequences).
#
#   scripts/prepare_device_carry.sh            # 200 pairs per sequence at most
#   FRAMES=50 scripts/prepare_device_carry.sh
set -euo pipefail
source "$(dirname "$0")/env.sh"

carry="${REPO_DIR}/.device_carry"
frames="${FRAMES:-200}"
if [[ ! -x ${BIN}/evaluate ]]; then
  echo "[carry] ${BIN}/evaluate not built: run make build first" >&2
  exit 1
fi
mkdir -p "${carry}/bearings"
rm -f "${carry}"/bearings/*.txt
exported=0
for name in kitti_turn kitti_straight euroc_v101_static euroc_mh01_shake; do
  if [[ ! -d ${DATA_DIR}/${name} ]]; then
    echo "[carry] skipping ${name}: ${DATA_DIR}/${name} not present"
    continue
  fi
  "${BIN}/evaluate" "${DATA_DIR}/${name}" --method paper --frames "${frames}" --backend cpu --quiet \
    --export-bearings "${carry}/bearings/${name}.txt" >/dev/null
  echo "[carry] ${name}: $(grep -c '^frame' "${carry}/bearings/${name}.txt") pairs"
  exported=$((exported + 1))
done

eigen="$(pkg-config --variable=includedir eigen3 2>/dev/null || true)/eigen3"
[[ -f ${eigen}/Eigen/Core ]] || eigen=/usr/include/eigen3
if [[ -f ${eigen}/Eigen/Core ]]; then
  rm -rf "${carry}/eigen3"
  mkdir -p "${carry}/eigen3"
  cp -r "${eigen}/Eigen" "${carry}/eigen3/"
  echo "[carry] Eigen headers from ${eigen}"
else
  echo "[carry] no Eigen headers found (make deps installs libeigen3-dev): cuda_estimator_check is built only where Eigen is installed" >&2
fi
echo "[carry] ${exported} bearing files; .device_carry is $(du -sh "${carry}" | cut -f1)"
