#!/usr/bin/env bash
# Installs the Debian 12 packages the project needs (only those missing), then configures and
# builds a CMake preset. Idempotent: with everything present it only runs an incremental build.
# Usage: scripts/setup.sh [preset]   (preset: release (default), asan (clang, with the libFuzzer
# targets), or fuzz: the libFuzzer targets alone, docs/fuzzing.md)
set -euo pipefail
cd "$(dirname "$0")/.."
preset=${1:-release}

packages=(cmake ninja-build g++ pkg-config
  libeigen3-dev libtbb-dev libopencv-dev libinsighttoolkit5-dev nlohmann-json3-dev libcli11-dev
  libembree-dev libhwy-dev libpng-dev libgtest-dev libgmock-dev libbenchmark-dev
  libvulkan-dev mesa-vulkan-drivers glslang-tools
  python3-dev pybind11-dev python3-pybind11 python3-numpy python3-pytest
  libopenmpi-dev openmpi-bin)
# clang 14 and its runtime libraries, which hold libFuzzer and the sanitizers for clang: the asan
# preset (the sanitizer pass, with the fuzz targets) and the fuzz preset build with them.
if [ "$preset" = asan ] || [ "$preset" = fuzz ]; then packages+=(clang libclang-rt-14-dev); fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

cmake --preset "$preset" >/dev/null
cmake --build --preset "$preset"
