#!/usr/bin/env bash
# Configures and builds ccm-slam-dds (Release) into ${BUILD_DIR:-build}. Extra arguments are
# passed to `cmake --build` (e.g. `--target ccm_agent`).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
JOBS="${JOBS:-$(nproc)}"
cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$BUILD_DIR" -j "$JOBS" "$@"
