# visual_gyro: the two set-up commands are `make demo` and `make test`; both install what is
# missing, build and run. CUDA=OFF builds without the CUDA backend (default AUTO: when nvcc exists).
SHELL := /bin/bash
CUDA ?= AUTO
DATA ?=
METHOD ?= vote
export CUDA DATA METHOD

.PHONY: all deps build demo test eval bench clean

all: build

deps:
	@scripts/install_deps.sh

build: deps
	@scripts/build.sh

demo: build
	@scripts/ros_demo.sh

test: build
	@scripts/run_tests.sh

eval: build
	@if [[ -z "$(DATA)" ]]; then echo "usage: make eval DATA=<sequence folder> [METHOD=vote|paper|essential5|fundamental8|...]"; exit 2; fi
	@scripts/eval.sh

bench: build
	@scripts/bench.sh

clean:
	rm -rf build out

# rviz on a replayed bag (real rosbag play, Xvfb), screenshot to out/rviz/replay.png.
# TRANSPORT=compressed in `make demo`: the bag holds JPEG images the node decodes.
TRANSPORT ?= raw
export TRANSPORT
.PHONY: rviz-shot
rviz-shot: build
	@scripts/rviz_shot.sh
