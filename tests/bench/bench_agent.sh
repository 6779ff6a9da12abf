#!/usr/bin/env bash
# Agent footprint (issue 29, docs/deployment.md "Footprint"): CPU milliseconds per frame by
# thread (tracking, local mapping, comm, the rest of the process) and peak RSS of
# `ccm_agent --standalone` at N = 25 / 50 / 100 local-map keyframes, next to bench_feature's
# ORB extraction CPU time per 752x480 frame measured in the same run (this machine's speed
# varies 2x from day to day: compare the ratio). "input" (reading, decoding or rendering the
# frames) is printed but not counted in "agent": a camera delivers frames for free.
# A benchmark, not a test. Usage: tests/bench/bench_agent.sh [BUILD_DIR]
#   env: NS="25 50 100", SIM_FRAMES=800 (hall3 agent 0; 0 skips it), REAL=0 skips ../shared/data.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD="${1:-$ROOT/build}"
AGENT="$BUILD/agent_runtime/ccm_agent"
FEATURE="$BUILD/tests/slam_core/feature/bench_feature"
DATA="$ROOT/../shared/data"
NS="${NS:-25 50 100}"
SIM_FRAMES="${SIM_FRAMES:-800}"
[[ -x "$AGENT" ]] || { echo "bench_agent: $AGENT missing (build ccm_agent)" >&2; exit 2; }
OUT="$(mktemp -d)"
trap 'rm -rf "$OUT"' EXIT

orb="n/a"
if [[ -x "$FEATURE" ]]; then
  orb="$("$FEATURE" 2>/dev/null | sed -n 's/.*(CPU \([0-9.]*\)).*/\1/p' | tail -1)"
fi
echo "bench_feature ORB extraction, adaptive threshold, 752x480: ${orb} ms CPU per frame"
echo
echo "| input | N | frames | tracking | mapping | comm | other | agent (no input, no set-up) | x ORB | input | set-up (once) | peak RSS MB | keyframes | tracked |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"

inputs=()  # name|base config (empty: defaults)|ccm_agent input arguments
[[ "$SIM_FRAMES" != 0 ]] && inputs+=("hall3||--sim hall3 --sim-agent 0 --max-frames $SIM_FRAMES")
if [[ "${REAL:-1}" != 0 ]]; then
  [[ -d "$DATA/ntsd150_euroc" ]] && inputs+=("ntsd150||--dataset $DATA/ntsd150_euroc")
  [[ -d "$DATA/kitti07_first160" ]] &&
    inputs+=("kitti07|$ROOT/deploy/config/agent-road.yaml|--dataset $DATA/kitti07_first160")
fi
for entry in "${inputs[@]}"; do
  IFS='|' read -r name base input <<<"$entry"
  read -r -a args <<<"$input"
  for n in $NS; do
    cfg="$OUT/$name-n$n.yaml"
    if [[ -n "$base" ]]; then grep -v '^max_keyframes:' "$base" >"$cfg"; else : >"$cfg"; fi
    echo "max_keyframes: $n" >>"$cfg"
    json="$OUT/$name-$n.json"
    "$AGENT" --standalone --log-level warn --config "$cfg" "${args[@]}" >"$json" 2>"$OUT/$name-$n.log" || {
      echo "| $name | $n | failed: $(tail -1 "$OUT/$name-$n.log") |"; continue; }
    python3 - "$json" "$name" "$n" "$orb" <<'PY'
import json, sys
s = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])
c = s["footprint"]["cpu_ms_per_frame"]
setup = c.get("setup", 0.0)  # the process before the first frame, spread per frame
agent = c["total"] - c["input"] - setup
orb = sys.argv[4]
ratio = f"{agent / float(orb):.1f}" if orb not in ("", "n/a") else "-"
print(f"| {sys.argv[2]} | {sys.argv[3]} | {s['frames']} | {c['tracking']:.1f} | {c['mapping']:.1f} | {c['comm']:.1f} | "
      f"{c['other']:.1f} | **{agent:.1f}** | {ratio} | {c['input']:.1f} | {setup * s['frames']:.0f} ms | "
      f"{s['footprint']['peak_rss_mb']:.0f} | "
      f"{s['keyframes_created']} | {100.0 * s['tracked'] / max(1, s['frames']):.0f} % |")
PY
  done
done
