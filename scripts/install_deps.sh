#!/usr/bin/env bash
# Installs every Debian package lisfm needs to build, test, run its demo and benchmarks.
# Non-interactive and idempotent: when everything is present it only checks and exits.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config git bc
  libeigen3-dev libceres-dev libsuitesparse-dev libgoogle-glog-dev libgflags-dev
  libopencv-dev libpcl-dev libflann-dev libnanoflann-dev libpng-dev libjpeg62-turbo-dev
  libyaml-cpp-dev libcli11-dev libspdlog-dev libfmt-dev nlohmann-json3-dev
  libsqlite3-dev sqlite3 libtbb-dev
  libgtest-dev libgmock-dev googletest libbenchmark-dev
  libembree-dev libopen3d-dev
  libopenmpi-dev openmpi-bin
  colmap
  python3-numpy python3-matplotlib
  librosbag-storage-dev libroscpp-core-dev libroslz4-dev libbz2-dev libconsole-bridge-dev
  libsensor-msgs-dev libstd-msgs-dev libgeometry-msgs-dev
  python3-rosbag python3-sensor-msgs
  pluginlib-dev libclass-loader-dev librcpputils-dev librcutils-dev libament-index-cpp-dev
  libboost-filesystem-dev
  clang-14 libclang-rt-14-dev
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

echo "install_deps: installing ${#missing[@]} missing packages: ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
echo "install_deps: done"
