#!/usr/bin/env bash
# Configures and builds ccm-slam-dds (Release) into ${BUILD_DIR:-build}. Extra arguments are
# passed to `cmake --build` (e.g. `--target ccm_agent`); CMAKE_ARGS to the configure step
# (e.g. "-DCCM_BUILD_TESTS=OFF").
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
JOBS="${JOBS:-$(nproc)}"
read -r -a configure_args <<<"${CMAKE_ARGS:-}"
cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release ${configure_args[@]+"${configure_args[@]}"} >/dev/null
cmake --build "$BUILD_DIR" -j "$JOBS" "$@"
