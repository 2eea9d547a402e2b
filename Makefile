# visual_gyro: the two set-up commands are `make demo` and `make test`; both install what is
# missing, build and run. CUDA=OFF builds without the CUDA backend (default AUTO: when nvcc exists).
SHELL := /bin/bash
CUDA ?= AUTO
DATA ?=
METHOD ?= vote
export CUDA DATA METHOD

.PHONY: all deps build demo test eval calibrate bench score sanitize soak fuzz clean settings-files

all: build

deps:
	@scripts/install_deps.sh

build: deps
	@scripts/build.sh

demo: build
	@scripts/ros_demo.sh

test: build
	@scripts/run_tests.sh

# cfg/VisualGyro.cfg, config/visual_gyro.yaml and the settings tables of README.md and doc/ros.md,
# generated from the settings tables (test_settings_consistency fails when a copy differs).
settings-files: build
	@scripts/generate_settings_files.sh

eval: build
	@if [[ -z "$(DATA)" ]]; then echo "usage: make eval DATA=<sequence folder> [METHOD=vote|paper|essential5|fundamental8|...]"; exit 2; fi
	@scripts/eval.sh

# Camera-IMU alignment of one recording (EuRoC folder with imu0/, or a bag: IMAGE_TOPIC, IMU_TOPIC).
IMAGE_TOPIC ?=
IMU_TOPIC ?=
export IMAGE_TOPIC IMU_TOPIC
calibrate: build
	@if [[ -z "$(DATA)" ]]; then echo "usage: make calibrate DATA=<EuRoC folder | file.bag> [IMAGE_TOPIC=... IMU_TOPIC=...]"; exit 2; fi
	@scripts/calibrate.sh

bench: build
	@scripts/bench.sh

# One score over the real footage, its hard variants and rendered scenes, every method, estimator
# seeds 1-3 pooled: out/score/score.md, score.csv, score.png, a last line of JSON. A benchmark, not
# in CI. SCORE_QUICK=1: one seed, a few frames.
score: build
	@scripts/score.sh

# Own workspace (build/.ws-sanitize, CUDA off) with ASan + UBSan; unit tests, rostests, evaluate.
sanitize: deps
	@scripts/sanitize.sh

# Replays a sequence forwards and backwards at 30 Hz through the node for MINUTES (default 10).
MINUTES ?= 10
soak: build
	@MINUTES=$(MINUTES) scripts/soak.sh

# libFuzzer targets (clang) for the image conversion and the dataset readers, FUZZ_SECONDS each.
FUZZ_SECONDS ?= 60
fuzz:
	@scripts/install_deps.sh fuzz
	@FUZZ_SECONDS=$(FUZZ_SECONDS) scripts/fuzz.sh

clean:
	rm -rf build out

# rviz on a replayed bag (real rosbag play, Xvfb), screenshot to out/rviz/replay.png.
# TRANSPORT=compressed in `make demo`: the bag holds JPEG images the node decodes.
TRANSPORT ?= raw
export TRANSPORT
.PHONY: rviz-shot
rviz-shot: build
	@scripts/rviz_shot.sh
