#!/usr/bin/env bash
# From scratch to "the arm64 agent flies like the native one", on a Debian 12 amd64 machine:
#   1. deploy/cross-build-arm64.sh OUT_DIR: host tools, arm64 sysroot, arm64 ccm_agent, .debs
#   2. the native binaries the comparison needs (ccm_agent, ccm_sim, ccm_eval, the default
#      vocabulary) in NATIVE_BUILD_DIR (default: build/), configured and built if missing
#      (needs deploy/install-deps.sh's packages)
#   3. deploy/check-arm64-agent.sh OUT_DIR NATIVE_BUILD_DIR (what ctest -L cross runs)
#
#   deploy/run-arm64-check.sh OUT_DIR [NATIVE_BUILD_DIR]     (JOBS=N, FRAMES=N)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="${1:?usage: deploy/run-arm64-check.sh OUT_DIR [NATIVE_BUILD_DIR]}"
NATIVE="${2:-$ROOT/build}"
JOBS="${JOBS:-$(nproc)}"
"$ROOT/deploy/cross-build-arm64.sh" "$OUT"
need=()
for b in agent_runtime/ccm_agent tests/sim/ccm_sim tools/eval/ccm_eval data/default_vocab_k10_l5.ccmvoc; do
  [ -e "$NATIVE/$b" ] || need+=("$b")
done
if [ ${#need[@]} -gt 0 ]; then
  echo "[arm64-check] native build $NATIVE: building ccm_agent ccm_sim ccm_eval ccm_default_vocab (missing: ${need[*]})"
  "$ROOT/deploy/install-deps.sh" --demo
  [ -f "$NATIVE/CMakeCache.txt" ] || cmake -S "$ROOT" -B "$NATIVE" -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$NATIVE" -j "$JOBS" --target ccm_agent ccm_sim_cli ccm_eval_cli ccm_default_vocab
fi
"$ROOT/deploy/check-arm64-agent.sh" "$OUT" "$NATIVE"
