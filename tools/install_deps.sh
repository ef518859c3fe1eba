#!/usr/bin/env bash
# Installs the Debian 12 packages banmo-ceres needs (only what is missing).
set -euo pipefail
packages=(
  build-essential cmake ninja-build ccache pkg-config
  libceres-dev libeigen3-dev libopencv-dev libcgal-dev libflann-dev liblz4-dev
  libgoogle-glog-dev libgflags-dev libgtest-dev libgmock-dev libbenchmark-dev
  libyaml-cpp-dev libcli11-dev libtinygltf-dev libstb-dev libtbb-dev
  libdraco-dev draco nlohmann-json3-dev
  gnuplot-nox clang-format
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "[deps] all ${#packages[@]} packages present"
  exit 0
fi
echo "[deps] installing: ${missing[*]}"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
