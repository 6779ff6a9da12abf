#!/usr/bin/env bash
# One command on a fresh Debian 12 machine: install dependencies, build, run the demo.
# Current demo: one ccm_server and three ccm_agent processes on this host exchange full
# keyframes through the real protocol (RELIABLE new data, BEST_EFFORT acks, resends) over
# the wifi.xml QoS profile while every process loses 20% of its incoming datagrams and
# delays the rest by 100 ms. The SLAM pipeline plugs into the same binaries as it lands.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
"$ROOT/deploy/install-deps.sh"
BUILD_DIR="$BUILD_DIR" "$ROOT/deploy/build.sh" --target ccm_agent ccm_server
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
exit $status
