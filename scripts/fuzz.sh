#!/usr/bin/env bash
# `make fuzz`: builds the libFuzzer targets in test/fuzz/ with clang (+ ASan, UBSan) under
# build/.fuzz and runs each for FUZZ_SECONDS (default 60) from a small seed corpus made here.
# A crash, hang or sanitizer report fails it (the reproducer is kept in build/.fuzz/<target>/).
# Last line: "N passed, N failed, N skipped".
set -uo pipefail
source "$(dirname "$0")/env.sh"
seconds="${FUZZ_SECONDS:-60}"
out="${REPO_DIR}/build/.fuzz"
mkdir -p "${out}"
if ! command -v clang++ >/dev/null; then
  echo "[fuzz] clang++ not found (Debian packages clang, libclang-rt-14-dev)"
  echo "0 passed, 0 failed, 1 skipped"
  exit 1
fi
flags=(-std=c++17 -g -O1 -fsanitize=fuzzer,address,undefined,float-cast-overflow -fno-sanitize-recover=all
  -I"${REPO_DIR}/include" -I"${REPO_DIR}/src/ros" -I/usr/include/opencv4 -I/usr/include/eigen3)
libs=(-lopencv_imgcodecs -lopencv_imgproc -lopencv_core -lrostime)
core=("${REPO_DIR}/src/core/camera_model.cpp")

build() {  # name, sources...
  local name="$1"
  shift
  echo "[fuzz] building ${name}"
  mkdir -p "${out}/bin"
  clang++ "${flags[@]}" "$@" "${libs[@]}" -o "${out}/bin/${name}"
}

passed=0
failed=0
build fuzz_to_gray "${REPO_DIR}/test/fuzz/fuzz_to_gray.cpp" "${REPO_DIR}/src/ros/ros_conversions.cpp" "${core[@]}" || failed=$((failed + 1))
build fuzz_sequence "${REPO_DIR}/test/fuzz/fuzz_sequence.cpp" "${REPO_DIR}/src/io/sequence.cpp" "${core[@]}" || failed=$((failed + 1))
estimator=("${REPO_DIR}"/src/voter/{cpu_voter,triple_batch}.cpp
  "${REPO_DIR}"/src/core/{frame_status,match_passes,rotation_estimator,rotation_refinement,candidate_refinement}.cpp
  "${REPO_DIR}"/src/core/{vote_candidates,vote_covariance}.cpp)
build fuzz_estimator -I"${REPO_DIR}/src/voter" -I"${REPO_DIR}/src/core" "${REPO_DIR}/test/fuzz/fuzz_estimator.cpp" \
  "${estimator[@]}" || failed=$((failed + 1))
front_end=("${REPO_DIR}"/src/core/{visual_gyro,feature_front_end,fast_detector,brief_kernels,hamming_kernels}.cpp
  "${REPO_DIR}"/src/core/{patch_alignment,fixed_point_gaussian,calibration_fit}.cpp)
build fuzz_pipeline -I"${REPO_DIR}/src/voter" -I"${REPO_DIR}/src/core" "${REPO_DIR}/test/fuzz/fuzz_pipeline.cpp" \
  "${front_end[@]}" "${estimator[@]}" "${core[@]}" -lopencv_features2d || failed=$((failed + 1))

# Seeds: a valid mono8 image and CameraInfo; a valid KITTI and EuRoC folder's files.
seed() {  # target, name, printf format...
  mkdir -p "${out}/corpus_$1"
  local target="$1" name="$2"
  shift 2
  printf "$@" >"${out}/corpus_${target}/${name}"
}
seed fuzz_to_gray mono8 '\x00\x00\x04\x00\x02\x00\x08\x00\x00\x00\x00\x00abcdefgh'
seed fuzz_to_gray mono16 '\x00\x01\x02\x00\x02\x00\x08\x00\x00\x00\x00\x0c\x01\x02\x03\x04\x05\x06\x07\x08'
seed fuzz_sequence kitti '\x00P0: 700 0 300 0 0 700 200 0 0 0 1 0\n\xff0.0\n0.1\n\xff1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 0\n'
seed fuzz_sequence euroc '\x01#t,f\n1000,1000.png\n2000,2000.png\n\xffintrinsics: [10, 10, 8, 6]\nresolution: [16, 12]\ndistortion_model: radtan\ndistortion_coefficients: [0.01, 0, 0, 0]\nT_BS:\n  data: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]\n\xff#t,wx,wy,wz\n500,0,0,1\n2500,0,0,1\n'
# The estimator: vote and paper on a structured frame of 200 matches (bearings within 25 deg of the
# axis, turned by a few degrees, over a third of them moved far: wrong matches), and on raw bytes.
mkdir -p "${out}/corpus_fuzz_estimator"
/usr/bin/env python3 - "${out}/corpus_fuzz_estimator" <<'PY'
import random, struct, sys
random.seed(1)
for name, options in (("vote", 0x20), ("paper", 0x21), ("vote_prior_refined", 0x32)):
    data = bytes([options, 40, 200, 0, 150, 120, 140])
    for _ in range(200):
        data += bytes([1]) + struct.pack("<fff", random.uniform(-0.4, 0.4), random.uniform(-0.3, 0.3), 1.0)
        data += bytes([random.randrange(256) for _ in range(3)])
    open(f"{sys.argv[1]}/{name}", "wb").write(data)
PY
seed fuzz_estimator raw '\x00\x10\x08\x00\x3f\x80\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00'
# The pipeline: a 200 x 150 texture shifted between four frames at 30 Hz (each pair estimated),
# the same with two settings changed, and a 40 x 40 image of raw bytes.
seed fuzz_pipeline texture '\x01\xb8\x86\xc8\x00\x07\x04\x04\x00\x00\x05\x04\x00\x00\x06\x04\x00\x00\x07\x04\x00\x00'
seed fuzz_pipeline texture_settings '\x01\xb8\x86\xc8\x02\x1e\x01\x00\x00\x40\x2d\x01\x00\x00\x40\x07\x04\x03\x00\x00\x05\x03\x00\x00\x06\x03\x00\x00\x07\x03\x00\x00'
seed fuzz_pipeline raw '\x00\x18\x18\x28\x00\x07abcdefghijklmnopqrstuvwxyz0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ'

for target in fuzz_to_gray fuzz_sequence fuzz_estimator fuzz_pipeline; do
  [[ -x ${out}/bin/${target} ]] || continue
  mkdir -p "${out}/${target}"
  echo "[fuzz] ${target} for ${seconds} s"
  if (cd "${out}/${target}" && "${out}/bin/${target}" -max_total_time="${seconds}" -timeout=10 -rss_limit_mb=2048 \
      -print_final_stats=1 "${out}/corpus_${target}" >"${out}/${target}.log" 2>&1); then
    grep -E "^stat::number_of_executed_units|^Done" "${out}/${target}.log" | tail -n 1
    passed=$((passed + 1))
  else
    echo "FAILED  ${target}: see ${out}/${target}.log and the reproducer in ${out}/${target}/"
    grep -m 5 -E "ERROR|runtime error|SUMMARY|deadly" "${out}/${target}.log" | sed 's/^/        /'
    failed=$((failed + 1))
  fi
done
echo "${passed} passed, ${failed} failed, 0 skipped"
((failed == 0))
