#!/usr/bin/env bash
# Builds the package in a catkin workspace under build/ (one workspace per CUDA setting).
set -euo pipefail
source "$(dirname "$0")/env.sh"
mkdir -p "${WS}/src"
shadow_package_dir
args=(-DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE=Release "-DVISUAL_GYRO_CUDA=${CUDA_MODE}")
if [[ ${CUDA_MODE} != OFF ]]; then
  nvcc_path=$(command -v nvcc || true)
  [[ -z ${nvcc_path} && -x /usr/local/cuda/bin/nvcc ]] && nvcc_path=/usr/local/cuda/bin/nvcc
  [[ -n ${nvcc_path} ]] && args+=("-DCMAKE_CUDA_COMPILER=${nvcc_path}")
fi
echo "[build] catkin workspace ${WS} (CUDA=${CUDA_MODE})"
cd "${WS}"
catkin_make "${args[@]}" -j"$(nproc)" "$@" 2>&1 | grep -v -E '^-- (Using|Found|Looking|Detecting|Check|Performing|Configuring done|Generating done)' || exit "${PIPESTATUS[0]}"
