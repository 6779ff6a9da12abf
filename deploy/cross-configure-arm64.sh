#!/usr/bin/env bash
# Configures (and with --build, builds) the lean onboard agent for arm64 with the multiarch
# toolchain file (cmake/toolchain-aarch64-debian.cmake). Prerequisites on a Debian 12 amd64
# host, once (docs/deployment.md, "arm64 cross build"):
#   sudo dpkg --add-architecture arm64 && sudo apt-get update
#   sudo apt-get install g++-aarch64-linux-gnu $(deploy/cross-configure-arm64.sh --print-packages)
#
#   deploy/cross-configure-arm64.sh [--build] [--print-packages]   (BUILD_DIR: build-arm64)
# On Debian 12 those arm64 -dev packages replace the amd64 ones (docs/deployment.md, "The arm64
# build"); the cross build that works beside a native one is deploy/cross-build-arm64.sh.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build-arm64}"
# The arm64 -dev packages the agent links (the host keeps fastddsgen, cmake, ccache).
ARM64_PACKAGES=(libfastrtps-dev:arm64 libfastcdr-dev:arm64 libeigen3-dev libopencv-dev:arm64 libceres-dev:arm64
  libsuitesparse-dev:arm64 libopengv-dev:arm64 libyaml-cpp-dev:arm64 libcli11-dev libspdlog-dev:arm64
  nlohmann-json3-dev libcereal-dev libgoogle-glog-dev:arm64)
BUILD=0
for arg in "$@"; do
  case "$arg" in
    --build) BUILD=1 ;;
    --print-packages) echo "${ARM64_PACKAGES[*]}"; exit 0 ;;
    *) echo "cross-configure-arm64.sh: unknown argument '$arg'" >&2; exit 2 ;;
  esac
done
command -v aarch64-linux-gnu-g++ >/dev/null || {
  echo "cross-configure-arm64.sh: aarch64-linux-gnu-g++ missing (apt install g++-aarch64-linux-gnu)" >&2; exit 1; }
cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DCCM_AGENT_ONLY=ON \
  -DCMAKE_TOOLCHAIN_FILE="$ROOT/cmake/toolchain-aarch64-debian.cmake"
if [ "$BUILD" = 1 ]; then
  cmake --build "$BUILD_DIR" -j "${JOBS:-$(nproc)}" --target ccm_agent
  file "$BUILD_DIR/agent_runtime/ccm_agent"
fi
