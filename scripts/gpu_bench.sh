#!/usr/bin/env bash
# The one command to run on a machine with a GPU (it needs nvcc, CMake and Python; no ROS, OpenCV
# or Eigen): builds cuda/ stand-alone, checks the CUDA voter against the CPU gold voter on the
# bearing files in .device_carry/bearings/*.txt (made by scripts/prepare_device_carry.sh) and on
# synthetic frames, checks the whole estimator on both backends against the files' truth (with
# Eigen's headers from .device_carry/eigen3 when the machine has none), runs the sanitizers on a
# small case, and times both voters.
#
#   scripts/gpu_bench.sh                 # everything
#   QUICK=1 scripts/gpu_bench.sh         # smoke test: fewer frames and benchmark points
#   CUDA_ARCHS=90 scripts/gpu_bench.sh   # architectures to build (default: the GPU's own)
#   ALLOW_NO_GPU=1 scripts/gpu_bench.sh  # on a machine without GPU: CPU gold parts only, no failure
#
# Files go to ${GPU_BENCH_OUT:-out/gpu} (console.log, environment.txt, build.log, check_*, sanitizer_*,
# bench_*). When GPU_BENCH_PACK names a folder, the output folder is also packed into
# ${GPU_BENCH_PACK}/gpu_bench.tar.gz with console.log beside it, for copying back in two files; unpack
# it with `mkdir -p out/gpu && tar xzf gpu_bench.tar.gz -C out/gpu` for `make bench`.
#
# Exit status: 0 when every check passed, 1 otherwise (the benchmarks still run).
set -uo pipefail
cd "$(dirname "$0")/.."

out_dir=${GPU_BENCH_OUT:-out/gpu}
build_dir=${BUILD_DIR:-build/cuda-standalone}
mkdir -p "${out_dir}"
rm -f "${out_dir}"/*.log "${out_dir}"/*.csv "${out_dir}"/*.txt
exec > >(tee "${out_dir}/console.log") 2>&1
log() { echo "[gpu_bench] $*"; }
status=0

export PATH="${PATH}:/usr/local/cuda/bin"
{
  date -u '+date: %Y-%m-%dT%H:%M:%SZ'
  echo "commit: $(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
  nvidia-smi --query-gpu=name,driver_version,compute_cap,memory.total --format=csv 2>&1
  nvcc --version 2>&1 | tail -2
  cmake --version | head -1
} | tee "${out_dir}/environment.txt"
gpu_name=$(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1)
log "GPU: ${gpu_name:-none found by nvidia-smi}"

archs=${CUDA_ARCHS:-}
if [[ -z ${archs} ]]; then
  archs=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader 2>/dev/null | head -1 | tr -d '. ')
  [[ ${archs} =~ ^[0-9]+$ ]] || archs="75;80;86;89;90"
fi
log "building cuda/ stand-alone for CUDA architectures ${archs}"
eigen_opt=()
if [[ -f .device_carry/eigen3/Eigen/Core ]]; then
  eigen_opt=("-DVISUAL_GYRO_EIGEN_INCLUDE_DIR=${PWD}/.device_carry/eigen3")
fi
if ! cmake -S cuda -B "${build_dir}" -DCMAKE_BUILD_TYPE=Release "-DVISUAL_GYRO_CUDA_ARCHITECTURES=${archs}" \
    "${eigen_opt[@]}" > "${out_dir}/build.log" 2>&1 ||
   ! cmake --build "${build_dir}" -j"$(nproc)" >> "${out_dir}/build.log" 2>&1; then
  tail -40 "${out_dir}/build.log"
  log "BUILD FAILED (log: ${out_dir}/build.log)"
  exit 1
fi
check="${build_dir}/cuda_voter_check"
estimator_check="${build_dir}/cuda_estimator_check"
bench="${build_dir}/cuda_voter_bench"

run() {  # run <log name> <command...>: tee the output, remember a failure
  log "$*"
  "${@:2}" 2>&1 | tee "${out_dir}/$1.log"
  local rc=${PIPESTATUS[0]}
  if [[ ${rc} -ne 0 ]]; then
    log "FAILED (exit ${rc}): ${*:2}"
    status=1
  fi
  return 0
}

require_gpu=(--require-gpu)
[[ -n ${ALLOW_NO_GPU:-} ]] && require_gpu=()
if [[ -n ${QUICK:-} ]]; then
  frames_opt=(--max-frames 20); synthetic=8; bench_opt=(--quick)
else
  frames_opt=(); synthetic=32; bench_opt=()
fi

# 1. CPU/GPU equivalence on the real sequences' matches, when they were exported.
shopt -s nullglob
files=(.device_carry/bearings/*.txt)
if (( ${#files[@]} )); then
  run check_files "${check}" "${require_gpu[@]}" "${frames_opt[@]}" --csv "${out_dir}/check_files.csv" "${files[@]}"
else
  log "no bearing files in .device_carry/bearings/: real-data check SKIPPED (see cuda/README.md to export them)"
fi
# 1b. The whole estimator (vote, paper) on both backends over the same files: the figures against
#     the files' truth within 5 % (the CUDA backend's accuracy goal), and the time split of an estimate.
if (( ${#files[@]} )) && [[ -x ${estimator_check} ]]; then
  run check_estimator "${estimator_check}" "${require_gpu[@]}" "${frames_opt[@]}" \
    --csv "${out_dir}/check_estimator.csv" "${files[@]}"
elif (( ${#files[@]} )); then
  log "cuda_estimator_check not built (no Eigen headers: scripts/prepare_device_carry.sh copies them into .device_carry/eigen3): estimator check SKIPPED"
fi
# 2. ... and on synthetic frames (pure rotation and forward driving, 30 % outliers).
run check_synthetic "${check}" "${require_gpu[@]}" --synthetic "${synthetic}" --csv "${out_dir}/check_synthetic.csv"

# 3. Memory errors and shared-memory races on a small case.
if command -v compute-sanitizer > /dev/null; then
  for tool in memcheck racecheck; do
    run "sanitizer_${tool}" compute-sanitizer --tool "${tool}" --error-exitcode 9 \
      "${check}" "${require_gpu[@]}" --synthetic 2 --hypotheses 3000
  done
else
  log "compute-sanitizer not found: sanitizer runs SKIPPED"
fi

# 4. Timings: estimation time against hypotheses and matches, CPU gold and CUDA.
run bench_synthetic "${bench}" "${bench_opt[@]}" --csv "${out_dir}/bench_synthetic.csv"
for f in "${files[@]}"; do
  name=$(basename "${f}" .txt)
  run "bench_${name}" "${bench}" "${bench_opt[@]}" --file "${f}" --csv "${out_dir}/bench_${name}.csv"
done

log "results in ${out_dir}:"
ls -l "${out_dir}"
pack=${GPU_BENCH_PACK:-}
if [[ -n ${pack} && -d ${pack} && $(cd "${pack}" && pwd) != $(cd "${out_dir}" && pwd) ]]; then
  tar czf "${pack}/gpu_bench.tar.gz" -C "${out_dir}" .
  log "packed into ${pack}/gpu_bench.tar.gz"
fi
if [[ ${status} -ne 0 ]]; then
  log "SOME CHECKS FAILED"
elif grep -q "GPU PART SKIPPED" "${out_dir}"/check_synthetic.log; then
  log "no CUDA device worked: only the CPU gold parts ran (ALLOW_NO_GPU); nothing on the GPU was checked or timed"
else
  log "ALL CHECKS PASSED on ${gpu_name:-unknown GPU}"
fi
[[ -n ${pack} && -d ${pack} ]] && cp "${out_dir}/console.log" "${pack}/console.log" 2>/dev/null
exit "${status}"
