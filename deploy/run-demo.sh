#!/usr/bin/env bash
# One command on a fresh Debian 12 machine: install dependencies, build, run the demo on the
# built-in synthetic multi-agent scenario "hall3" (3 drones in an indoor hall).
#  1. Link: one ccm_server and three ccm_agent processes exchange full keyframes through the
#     real protocol (RELIABLE new data, BEST_EFFORT acks, resends) over the wifi.xml QoS
#     profile while every process loses 20% of its incoming datagrams and delays the rest
#     by 100 ms.
#  2. Onboard VO: each of the three agents flies its hall3 trajectory (frames rendered in
#     process) with the monocular VO, standalone, and ccm_eval scores the trajectories
#     against the simulator's ground truth (table + plot).
# The server-side collaborative mapping (place recognition, fusion) is not wired in yet.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
"$ROOT/deploy/install-deps.sh"
BUILD_DIR="$BUILD_DIR" "$ROOT/deploy/build.sh" --target ccm_agent ccm_server ccm_eval_cli
BIN="$BUILD_DIR"
QOS="$ROOT/qos_profiles/wifi.xml"
DROP="${DEMO_DROP:-0.2}"
DELAY="${DEMO_DELAY_MS:-100}"
KFS="${DEMO_KEYFRAMES:-40}"
OUT="$(mktemp -d)"
trap 'kill $(jobs -p) 2>/dev/null || true' EXIT
common=(--qos "$QOS" --domain 42 --drop "$DROP" --delay-ms "$DELAY")
echo "[demo] 1 server + 3 agents, ${KFS} keyframes each (~55 kB), drop=${DROP}, delay=${DELAY} ms, logs in $OUT"
"$BIN/server_runtime/ccm_server" "${common[@]}" --idle-exit 8 --duration 180 >"$OUT/server.log" 2>&1 &
server_pid=$!
pids=()
for id in 1 2 3; do
  "$BIN/agent_runtime/ccm_agent" "${common[@]}" --agent-id "$id" --link-demo "$KFS" --drain 60 \
    >"$OUT/agent$id.log" 2>&1 &
  pids+=($!)
done
status=0
for id in 1 2 3; do
  wait "${pids[$((id - 1))]}" || status=1
  echo "[demo] agent $id: $(grep '^{' "$OUT/agent$id.log" | tail -1)"
done
wait "$server_pid" || status=1
echo "[demo] server: $(grep '^{' "$OUT/server.log" | tail -1)"
if [ $status -eq 0 ]; then echo "[demo] OK: every keyframe of every agent reached the server and was acknowledged"; fi

FRAMES="${DEMO_FRAMES:-600}"
echo "[demo] onboard VO: 3 hall3 agents, ${FRAMES} frames each (752x480, 20 Hz), standalone"
vo_pids=()
for a in 0 1 2; do
  "$BIN/agent_runtime/ccm_agent" --standalone --sim hall3 --sim-agent "$a" --agent-id $((a + 1)) \
    --max-frames "$FRAMES" --trajectory "$OUT/vo_agent$a.txt" --keyframes "$OUT/vo_agent${a}_kf.txt" \
    --ground-truth "$OUT/gt_agent$a.txt" >"$OUT/vo_agent$a.log" 2>&1 &
  vo_pids+=($!)
done
for a in 0 1 2; do
  wait "${vo_pids[$a]}" || status=1
  echo "[demo] agent $a VO: $(grep 'done:' "$OUT/vo_agent$a.log" | sed 's/.*done: //')"
done
# Each agent's VO has its own frame and scale: read the per-agent rows (the JOINT row needs a
# common map frame, which server-side fusion will provide); one plot per agent.
"$BIN/tools/eval/ccm_eval" --gt "$OUT/gt_agent0.txt" --est "$OUT/vo_agent0.txt" \
  --gt "$OUT/gt_agent1.txt" --est "$OUT/vo_agent1.txt" --gt "$OUT/gt_agent2.txt" --est "$OUT/vo_agent2.txt" \
  --name agent0 --name agent1 --name agent2 --json "$OUT/vo_eval.json" || status=1
for a in 0 1 2; do
  "$BIN/tools/eval/ccm_eval" --gt "$OUT/gt_agent$a.txt" --est "$OUT/vo_agent$a.txt" --name "agent$a" \
    --plot "$OUT/vo_agent$a.png" >/dev/null || status=1
done
echo "[demo] trajectories, logs, vo_eval.json and plots vo_agent{0,1,2}.png are in $OUT"
exit $status
