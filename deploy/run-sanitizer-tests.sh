#!/usr/bin/env bash
# Dedicated sanitizer job (issue 11): builds the transport tests with AddressSanitizer and
# UndefinedBehaviorSanitizer (CCM_SANITIZE=ON, separate build tree) and runs the conversion,
# rejection and fuzz tests: >= 100,000 mutated and truncated keyframe / map point / update /
# server messages through conversion and a server back-end. Any sanitizer finding fails the
# job (halt_on_error). Takes ~20 min on 2 cores from scratch (ccache helps later runs); kept
# out of the main CI run, which must stay under 30 min.
# Status (2026-11-23): the 27 size, conversion and rejection tests run clean; the fuzz test
# aborts in its set-up, inside Debian's libopengv (relative_pose::fivept_stewenius frees a
# block it did not allocate: "bad-free", reached from the VO's two-view initialization that
# makes the base messages), before any mutated message is converted. Open: the fuzz test
# needs base messages that do not go through OpenGV under ASan, or an OpenGV fix.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build-asan}"
JOBS="${JOBS:-$(nproc)}"
"$ROOT/deploy/install-deps.sh"
cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCCM_SANITIZE=ON >/dev/null
cmake --build "$BUILD_DIR" -j "$JOBS" --target transport_test
export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:abort_on_error=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
# Fast DDS itself is not instrumented; its one-time allocations at exit are not ours.
export LSAN_OPTIONS="suppressions=$ROOT/deploy/lsan.supp"
"$BUILD_DIR/tests/transport/transport_test" --gtest_filter='MsgConv*:MsgRej*:MsgConversionFuzz*:MsgSize*'
echo "[sanitizers] conversion, rejection and fuzz tests clean under ASan + UBSan"
