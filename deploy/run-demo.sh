#!/usr/bin/env bash
# One command on a fresh Debian 12 machine: install dependencies, build, run the real system
# on the built-in synthetic scenario "hall3" (3 drones in an indoor hall):
# one ccm_server and three ccm_agent processes (real monocular VO on frames the simulator
# renders in process) talk over DDS with the shipped wifi.xml QoS profiles, while every
# process loses DEMO_DROP of its incoming datagrams and delays the rest by DEMO_DELAY_MS.
# The agents stream keyframes and points, the server fuses the maps, closes loops and shares
# the map back. Progress every few seconds; at the end a summary (per-agent and
# collaborative ATE against the simulator's ground truth, fusion and loop events, traffic
# per agent both ways) and the folder demo-out/: summary.json, agent<i>_keyframes.tum (in
# the fused map's frame), map.ply, map_top.png, the processes' logs.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
"$ROOT/deploy/install-deps.sh" --demo
# Tests off: the demo needs neither GoogleTest nor the test binaries (run-tests.sh turns them on).
CMAKE_ARGS="-DCCM_BUILD_TESTS=OFF" BUILD_DIR="$BUILD_DIR" "$ROOT/deploy/build.sh" --target ccm_agent ccm_server ccm_eval_cli
BIN="$BUILD_DIR"
QOS="$ROOT/qos_profiles/wifi.xml"
DROP="${DEMO_DROP:-0.1}"
DELAY="${DEMO_DELAY_MS:-50}"
FRAMES="${DEMO_FRAMES:-1601}"   # all of hall3: 80 s of flight per agent
RATE="${DEMO_RATE:-0.5}"        # half real time: three VOs and the server share 2 cores
OUT="${DEMO_OUT:-$PWD/demo-out}"
DOMAIN="${DEMO_DOMAIN:-42}"
read -r -a AGENT_ARGS <<<"${DEMO_AGENT_ARGS:-}"  # extra ccm_agent arguments, e.g. "--config my-agent.yaml"
rm -rf "$OUT"
mkdir -p "$OUT"
trap 'kill $(jobs -p) 2>/dev/null || true' EXIT
common=(--qos "$QOS" --domain "$DOMAIN" --drop "$DROP" --delay-ms "$DELAY")
echo "[demo] 1 server + 3 agents on hall3 (${FRAMES} frames each at ${RATE}x real time), drop=${DROP}, delay=${DELAY} ms"
echo "[demo] output and logs: $OUT"
"$BIN/server_runtime/ccm_server" "${common[@]}" --idle-exit 5 --duration 900 --progress 5 --out "$OUT/server" \
  >"$OUT/server.log" 2>&1 &
server_pid=$!
pids=()
for id in 1 2 3; do
  "$BIN/agent_runtime/ccm_agent" "${common[@]}" --agent-id "$id" --sim hall3 --sim-agent $((id - 1)) \
    --max-frames "$FRAMES" --rate "$RATE" --drain 60 --ground-truth "$OUT/agent${id}_ground_truth.tum" \
    ${AGENT_ARGS[@]+"${AGENT_ARGS[@]}"} >"$OUT/agent$id.log" 2>&1 &
  pids+=($!)
done
# Live progress: the newest progress line of every process.
while kill -0 "${pids[@]}" 2>/dev/null; do
  sleep 10
  for id in 1 2 3; do
    line=$(grep -a "frames " "$OUT/agent$id.log" | tail -1 | sed 's/^\[[^]]*\] \[info\] //') || true
    [ -n "$line" ] && echo "[demo] agent $id: $line"
  done
  line=$(grep -a " s: maps" "$OUT/server.log" | tail -1 | sed 's/^\[[^]]*\] \[info\] //') || true
  [ -n "$line" ] && echo "[demo] server: $line"
done
status=0
for id in 1 2 3; do wait "${pids[$((id - 1))]}" || { echo "[demo] agent $id failed, see $OUT/agent$id.log"; status=1; }; done
wait "$server_pid" || { echo "[demo] server failed, see $OUT/server.log"; status=1; }
[ -f "$OUT/server/server.json" ] || { echo "[demo] the server wrote no outputs"; exit 1; }
cp "$OUT"/server/agent*_keyframes.tum "$OUT/server/map.ply" "$OUT/server/map_top.png" "$OUT/"
"$BIN/tools/eval/ccm_eval" \
  --gt "$OUT/agent1_ground_truth.tum" --est "$OUT/agent1_keyframes.tum" \
  --gt "$OUT/agent2_ground_truth.tum" --est "$OUT/agent2_keyframes.tum" \
  --gt "$OUT/agent3_ground_truth.tum" --est "$OUT/agent3_keyframes.tum" \
  --name agent1 --name agent2 --name agent3 --json "$OUT/eval.json" --plot "$OUT/ate_top.png" >"$OUT/eval.txt" 2>&1 ||
  { echo "[demo] evaluation failed: $(tail -3 "$OUT/eval.txt")"; status=1; }
python3 "$ROOT/deploy/demo_summary.py" "$OUT" 3 || status=1
echo "[demo] summary.json, map.ply, map_top.png, ate_top.png and trajectories are in $OUT"
exit $status
