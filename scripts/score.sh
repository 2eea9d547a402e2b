#!/usr/bin/env bash
# `make score`: one score over all the real footage and its hard variants. Every method of
# `evaluate --list-methods`, on the same matches per run, on: the shared real sequences present;
# their hard variants (dim, noisy JPEG footage, pairs several frames apart, wrong matches, both at
# once, frames downscaled to a quarter); and rendered scenes (near structure, over four textures; a
# dim blurred room, a blurred 1280 x 720 room over four textures, a hand-held room, the same through
# a phone-like rolling shutter, also at half the frame rate, the hand-held room moved by centimetres
# through a global and a rolling shutter, drone_near through the shutter, and the blurred 1280 x 720
# room through a rolling shutter with the hand moving the camera by centimetres, over four textures
# (the dim rooms' few, noisy matches change with the rendering), with three times the noise, and
# lit brighter at that noise, with hundreds of noisy matches). Each case runs with estimator seeds
# 1-3; the per-frame CSVs are pooled by scripts/score.py into out/score/score.md, score.csv,
# score.png and a last line of JSON (also out/score/score.json).
#
# Kept to about 15 minutes on two cores by frame limits: at most SCORE_FRAMES pairs per case (default
# 30: the first 30 pairs of every real sequence and variant), renders of SCORE_RENDER_FRAMES frames
# (default 31, so 30 pairs). Renders are made once into out/score/rendered and reused
# while the render command and the render_sequence program are unchanged.
# SCORE_QUICK=1: a smoke run (one seed, 6 pairs per case, 8-frame renders).
# SCORE_ABLATION=1: also the vote method without each of its parts (`evaluate --list-ablations`),
# on the same matches; score.md then holds the ablation table. SCORE_METHODS: a comma-separated
# list instead of `evaluate --list-methods`.
# SCORE_SEEDS, SCORE_FRAMES, SCORE_RENDER_FRAMES, SCORE_BACKEND (cpu; auto uses CUDA where it
# works), SCORE_OUT override.
set -euo pipefail
source "$(dirname "$0")/env.sh"

OUT="${SCORE_OUT:-${REPO_DIR}/out/score}"
BACKEND="${SCORE_BACKEND:-cpu}"
if [[ ${SCORE_QUICK:-0} == 1 ]]; then
  SEEDS="${SCORE_SEEDS:-1}"
  FRAMES="${SCORE_FRAMES:-6}"
  RENDER_FRAMES="${SCORE_RENDER_FRAMES:-8}"
else
  SEEDS="${SCORE_SEEDS:-1 2 3}"
  FRAMES="${SCORE_FRAMES:-30}"
  RENDER_FRAMES="${SCORE_RENDER_FRAMES:-31}"
fi
EVAL="${BIN}/evaluate"
RENDER="${BIN}/render_sequence"
PY=/usr/bin/python3

for tool in "${EVAL}" "${RENDER}"; do
  if [[ ! -x ${tool} ]]; then
    echo "[score] ${tool} not built (run make build)" >&2
    exit 1
  fi
done
if ! "${PY}" -c 'import matplotlib, numpy' 2>/dev/null; then
  echo "[score] ${PY} lacks matplotlib/numpy (Debian: python3-matplotlib python3-numpy; make deps installs them)" >&2
  exit 1
fi

METHODS="${SCORE_METHODS:-$("${EVAL}" --list-methods)}"
if [[ ${SCORE_ABLATION:-0} == 1 ]]; then
  METHODS="${METHODS},$("${EVAL}" --list-ablations)"
fi
mkdir -p "${OUT}/logs" "${OUT}/csv" "${OUT}/rendered"
rm -f "${OUT}"/csv/*.csv "${OUT}"/logs/eval_*.log
MANIFEST="${OUT}/manifest.tsv"
: >"${MANIFEST}"
start_all=${SECONDS}
echo "[score] methods ${METHODS}; seeds ${SEEDS}; at most ${FRAMES} pairs per case; backend ${BACKEND}; out ${OUT}"

# render <name> <render_sequence options...>: renders into rendered/<name> unless a render with the
# same options, newer than the program and the renderer's library, is there already.
render() {
  local name=$1
  shift
  local dir="${OUT}/rendered/${name}" spec="--frames ${RENDER_FRAMES} $*" stamp program fresh=1
  stamp="${dir}/render_options.txt"
  if [[ -f ${stamp} && $(cat "${stamp}") == "${spec}" ]]; then
    for program in "${RENDER}" "${WS}"/devel/lib/libvisual_gyro_sim.*; do
      [[ -e ${program} && ${program} -nt ${stamp} ]] && fresh=0
    done
    ((fresh)) && return 0
  fi
  rm -rf "${dir}"
  local t0=${SECONDS}
  if "${RENDER}" --frames "${RENDER_FRAMES}" "$@" --out "${dir}" >"${OUT}/logs/render_${name}.log" 2>&1; then
    echo "${spec}" >"${stamp}"
    echo "[score] rendered ${name} in $((SECONDS - t0)) s"
  else
    echo "[score] render_sequence ${name} failed; see ${OUT}/logs/render_${name}.log" >&2
    rm -rf "${dir}"
  fi
}

# run_case <case> <folder> <description> [evaluate options...]: every method, once per seed.
run_case() {
  local case=$1 folder=$2 description=$3
  shift 3
  if [[ ! -d ${folder} ]]; then
    echo "[score] skipping ${case}: ${folder} not present"
    return 0
  fi
  local t0=${SECONDS} seed
  for seed in ${SEEDS}; do
    local csv="${OUT}/csv/${case}_seed${seed}.csv" log="${OUT}/logs/eval_${case}_seed${seed}.log"
    if "${EVAL}" "${folder}" --method "${METHODS}" --backend "${BACKEND}" --quiet --frames "${FRAMES}" \
        --seed "${seed}" --csv "${csv}" "$@" >"${log}" 2>&1; then
      printf '%s\t%s\t%s\t%s\t%s\n' "${case}" "${seed}" "${csv}" "${log}" "${description}" >>"${MANIFEST}"
    else
      echo "[score] evaluate failed on ${case} seed ${seed}; see ${log}" >&2
      tail -3 "${log}" >&2
    fi
  done
  echo "[score] ${case}: $((SECONDS - t0)) s"
}

# 1. Renders (reused between runs).
# Renderer seeds of the scenes rendered over other textures as well (drone_near and the two
# 1280 x 720 dim rooms).
TEXTURE_SEEDS=(4 12 16)
render drone_near --preset drone_near
for texture in "${TEXTURE_SEEDS[@]}"; do
  render "drone_near_texture${texture}" --preset drone_near --seed "${texture}"
done
render dim_blur3_jpeg75 --preset dim --blur 3 --jpeg 75
dim_blur15_720p_options=(--preset dim --blur 15 --jpeg 60 --width 1280 --height 720 --focal 900)
render dim_blur15_720p "${dim_blur15_720p_options[@]}"
for texture in "${TEXTURE_SEEDS[@]}"; do
  render "dim_blur15_720p_texture${texture}" "${dim_blur15_720p_options[@]}" --seed "${texture}"
done
render handheld --preset handheld
render handheld_rs --preset handheld_rs
render handheld_rs_15hz --preset handheld_rs --rate 15
render handheld_5cm --preset handheld --hand-translation-cm 5
render handheld_rs_5cm --preset handheld_rs --hand-translation-cm 5
render drone_near_rs --preset drone_near --rolling-shutter-ms 28
dim_hand_rs_options=(--preset dim --blur 15 --jpeg 60 --width 1280 --height 720 --focal 900 --rolling-shutter-ms 33
  --hand-translation-cm 6)
render dim_hand_rs "${dim_hand_rs_options[@]}"
for texture in "${TEXTURE_SEEDS[@]}"; do
  render "dim_hand_rs_texture${texture}" "${dim_hand_rs_options[@]}" --seed "${texture}"
done
# The same room at the noise of a dim real camera (6 grey levels on a 30-level scene, before the
# JPEG): a pair's matches lie about a pixel from where the motion puts them.
render dim_hand_rs_noise6 "${dim_hand_rs_options[@]}" --noise 6
# The same room at 4 grey levels of noise, over the four textures: some 200 matches a pair, few and
# noisy enough that a general motion's rotation spreads further than a pure rotation's translation
# bias, as hand-held footage of a dim real room showed.
render dim_hand_rs_noise4 "${dim_hand_rs_options[@]}" --noise 4
for texture in "${TEXTURE_SEEDS[@]}"; do
  render "dim_hand_rs_noise4_texture${texture}" "${dim_hand_rs_options[@]}" --noise 4 --seed "${texture}"
done
# The same room lit three times brighter (90 grey levels) at that noise: some 600 matches a pair,
# as many as a hand-held 1280 x 720 camera gives in a dim real room, so that the general motion
# rests on hundreds of noisy matches rather than a few dozen.
render hand_rs_720p_noise6 "${dim_hand_rs_options[@]}" --contrast 3 --noise 6

# 2. The shared real sequences at their own rate.
for name in kitti_turn kitti_straight euroc_v101_static euroc_mh01_shake; do
  run_case "${name}" "${DATA_DIR}/${name}" "${name}, every pair at the camera's rate"
done

# 3. Dim, noisy, JPEG-compressed real footage (the noise drawn from the seed).
shake="${DATA_DIR}/euroc_mh01_shake"
run_case mh01_contrast0.08 "${shake}" "euroc_mh01_shake, contrast 0.08, noise 3, JPEG 75" \
  --contrast 0.08 --noise 3 --jpeg 75
run_case mh01_contrast0.05 "${shake}" "euroc_mh01_shake, contrast 0.05, noise 3, JPEG 75" \
  --contrast 0.05 --noise 3 --jpeg 75
run_case kitti_turn_contrast0.05 "${DATA_DIR}/kitti_turn" "kitti_turn, contrast 0.05, noise 3, JPEG 75" \
  --contrast 0.05 --noise 3 --jpeg 75

# 4. Pairs K frames apart near structure (K times the motion and parallax of a pair).
for stride in 2 3 4 5; do
  run_case "mh01_stride${stride}" "${shake}" "euroc_mh01_shake, image k paired with image k-${stride}" \
    --stride "${stride}"
done

# 5. Wrong pairings injected among the matches before any method runs.
for fraction in 0.5 0.7; do
  run_case "mh01_outliers${fraction}" "${shake}" "euroc_mh01_shake, ${fraction/0./}0 % of the matches wrong" \
    --outliers "${fraction}"
done
run_case mh01_stride2_outliers0.5 "${shake}" "euroc_mh01_shake, image k paired with image k-2, 50 % of the matches wrong" \
  --stride 2 --outliers 0.5

# 5b. Small images: frames downscaled with their intrinsics. At a quarter of their size the
# shared sequences are still estimated; below it vote declares its estimates invalid (inliers too
# concentrated), which the pooled errors would score as no rotation.
for name in kitti_turn euroc_mh01_shake; do
  run_case "${name}_scale0.25" "${DATA_DIR}/${name}" "${name} downscaled to a quarter (intrinsics scaled)" \
    --scale 0.25
done

# 5c. An object moving through one side of the view, its matches turned by its own motion
# (evaluate --moving-region): a vehicle passing a drive; a large region moving slowly near
# structure (water, a crowd), which a close scene's parallax can explain as well.
run_case kitti_turn_moving0.3 "${DATA_DIR}/kitti_turn" \
  "kitti_turn, the rightmost 30 % of the matches moving by a further 2 deg a pair" --moving-region 0.3 --moving-deg 2
run_case mh01_moving0.3 "${shake}" \
  "euroc_mh01_shake, the rightmost 30 % of the matches moving by a further 0.5 deg a pair" \
  --moving-region 0.3 --moving-deg 0.5

# 6. Rendered scenes (exact truth).
run_case drone_near "${OUT}/rendered/drone_near" "rendered drone_near: shaken 1-2 m from boxes, 20 Hz"
for texture in "${TEXTURE_SEEDS[@]}"; do
  run_case "drone_near_texture${texture}" "${OUT}/rendered/drone_near_texture${texture}" \
    "rendered drone_near's motion over the boxes of renderer seed ${texture} (other textures, other basins)"
done
run_case dim_blur3_jpeg75 "${OUT}/rendered/dim_blur3_jpeg75" "rendered dim room, 3 px motion blur, JPEG 75, 30 Hz"
run_case dim_blur15_720p "${OUT}/rendered/dim_blur15_720p" \
  "rendered dim room at 1280 x 720 (f = 900 px), 15 px motion blur, JPEG 60, 30 Hz"
for texture in "${TEXTURE_SEEDS[@]}"; do
  run_case "dim_blur15_720p_texture${texture}" "${OUT}/rendered/dim_blur15_720p_texture${texture}" \
    "the same camera and motion through the dim room of renderer seed ${texture} (other doors, boxes, textures and noise)"
done
run_case handheld "${OUT}/rendered/handheld" "rendered hand-held room, 30 Hz"
run_case handheld_moving0.45 "${OUT}/rendered/handheld" \
  "rendered hand-held room, the rightmost 45 % of the matches moving by a further 2 deg a pair (a person walking past)" \
  --moving-region 0.45 --moving-deg 2
run_case handheld_rs "${OUT}/rendered/handheld_rs" \
  "rendered hand-held room through a rolling shutter (28 ms read-out; stamps and poses the middle row's), 30 Hz"
run_case handheld_rs_15hz "${OUT}/rendered/handheld_rs_15hz" \
  "the same hand-held motion through the same rolling shutter at 15 Hz (twice the motion a pair)"
run_case handheld_5cm "${OUT}/rendered/handheld_5cm" \
  "rendered hand-held room, the hand moving the camera by +-5 cm (a phone or camera carried by hand), 30 Hz"
run_case handheld_rs_5cm "${OUT}/rendered/handheld_rs_5cm" \
  "the same, the hand moving the camera by +-5 cm, through the 28 ms rolling shutter"
run_case drone_near_rs "${OUT}/rendered/drone_near_rs" \
  "rendered drone_near through a rolling shutter (28 ms read-out), 20 Hz: translation near structure"
run_case dim_hand_rs "${OUT}/rendered/dim_hand_rs" \
  "rendered dim room at 1280 x 720 (f = 900 px), 15 px blur, JPEG 60, through a 33 ms rolling shutter, the hand moving the camera by +-6 cm, 30 Hz"
for texture in "${TEXTURE_SEEDS[@]}"; do
  run_case "dim_hand_rs_texture${texture}" "${OUT}/rendered/dim_hand_rs_texture${texture}" \
    "rendered dim_hand_rs's motion through the room of renderer seed ${texture} (other doors, boxes, textures and noise)"
done
run_case dim_hand_rs_noise6 "${OUT}/rendered/dim_hand_rs_noise6" \
  "rendered dim_hand_rs with three times its pixel noise (6 grey levels before the JPEG), as a dim real camera gives"
run_case dim_hand_rs_noise4 "${OUT}/rendered/dim_hand_rs_noise4" \
  "rendered dim_hand_rs with twice its pixel noise (4 grey levels before the JPEG): some 200 matches a pair"
for texture in "${TEXTURE_SEEDS[@]}"; do
  run_case "dim_hand_rs_noise4_texture${texture}" "${OUT}/rendered/dim_hand_rs_noise4_texture${texture}" \
    "rendered dim_hand_rs_noise4's motion through the room of renderer seed ${texture}"
done
run_case hand_rs_720p_noise6 "${OUT}/rendered/hand_rs_720p_noise6" \
  "rendered dim_hand_rs_noise6 lit three times brighter (90 grey levels): some 600 matches a pair, noisy"

# 7. Summary.
machine="$(lscpu 2>/dev/null | sed -n 's/^Model name:[[:space:]]*//p' | head -1), $(nproc) cores"
date_utc="$(date -u '+%Y-%m-%d %H:%M UTC')"
elapsed=$((SECONDS - start_all))
"${PY}" "${REPO_DIR}/scripts/score.py" --manifest "${MANIFEST}" --out "${OUT}" --machine "${machine}" \
  --date "${date_utc}" --note "At most ${FRAMES} pairs per case (renders: ${RENDER_FRAMES} frames); backend ${BACKEND}; \
evaluation and renders took ${elapsed} s." >"${OUT}/summary.log" 2>&1 ||
  { cat "${OUT}/summary.log" >&2; exit 1; }
echo "[score] machine: ${machine}; total $((SECONDS - start_all)) s; files in ${OUT} (score.md, score.csv, score.png)"
tail -1 "${OUT}/summary.log"
