#!/usr/bin/env bash
# Installs the Debian packages visual_gyro needs, only those missing (apt-get; sudo when not root).
set -euo pipefail
packages=(
  build-essential cmake pkg-config catkin python3-catkin-pkg
  ros-core-dev rosbash python3-rostopic python3-rosnode python3-roslaunch
  libnodeletlib-dev libnodeletlib-tools pluginlib-dev
  libcv-bridge-dev libimage-transport-dev libtf2-ros-dev libtf2-geometry-msgs-dev
  librostest-dev python3-rostest librosbag-dev python3-rosbag
  libdynamic-reconfigure-config-init-mutex-dev python3-dynamic-reconfigure
  libdiagnostic-updater-dev libmessage-filters-dev
  ros-message-generation ros-std-msgs ros-sensor-msgs ros-geometry-msgs ros-visualization-msgs
  python3-sensor-msgs python3-diagnostic-msgs python3-std-srvs
  rviz xvfb imagemagick python3-pil
  libopencv-dev libeigen3-dev libopengv-dev libgtest-dev python3-numpy python3-matplotlib
)
# `install_deps.sh fuzz`: also the clang toolchain with libFuzzer (make fuzz).
if [[ ${1:-} == fuzz ]]; then packages+=(clang libclang-rt-14-dev); fi
missing=()
for p in "${packages[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ $status == "install ok installed" ]] || missing+=("$p")
done
if ((${#missing[@]} == 0)); then
  echo "[deps] all ${#packages[@]} Debian packages present"
  exit 0
fi
echo "[deps] installing: ${missing[*]}"
sudo=""
if [[ $(id -u) != 0 ]]; then sudo="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
