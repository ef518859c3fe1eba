#!/usr/bin/env bash
# Installs the Debian 12 packages banmo-ceres needs (only what is missing),
# then the Khronos glTF validator from the npm registry into tools/node
# (`npm ci`, pinned by tools/node/package-lock.json; docs/report.md).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
packages=(
  build-essential cmake ninja-build ccache pkg-config
  libceres-dev libeigen3-dev libopencv-dev libcgal-dev libflann-dev liblz4-dev
  libgoogle-glog-dev libgflags-dev libgtest-dev libgmock-dev libbenchmark-dev
  libyaml-cpp-dev libcli11-dev libtinygltf-dev libstb-dev libtbb-dev
  libdraco-dev draco nlohmann-json3-dev
  gnuplot-nox clang-format
  libjs-three chromium
)
# Node.js for the glTF validator: Debian's, unless a node is already there.
command -v node >/dev/null 2>&1 || packages+=(nodejs npm)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "[deps] all ${#packages[@]} packages present"
else
  echo "[deps] installing: ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
node_dir="$root/tools/node"
if [ ! -f "$node_dir/node_modules/gltf-validator/package.json" ] ||
  [ "$node_dir/package-lock.json" -nt "$node_dir/node_modules/.package-lock.json" ]; then
  echo "[deps] npm ci in tools/node (gltf-validator)"
  (cd "$node_dir" && npm ci --no-audit --no-fund --loglevel=error)
else
  echo "[deps] tools/node: gltf-validator present"
fi
