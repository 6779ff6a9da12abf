#!/usr/bin/env bash
# Long flight (issues 28 and 29): one ccm_agent flies hall3's agent-0 loop for LONG_MINUTES
# (default 60), against a ccm_server that saves its map file every LONG_AUTOSAVE s (default
# 20, the packaged value) over qos_profiles/wifi.xml, or with LONG_SERVER=0 alone
# (--standalone: a flight without a ground station). Every LONG_SAMPLE_S s
# flight_sampler.py writes OUT/samples.csv: both processes' resident memory and CPU, and the
# agent's frames, keyframes, unacknowledged keyframes and backlog from its --metrics endpoint.
# At the end it prints the agent's summary counters and the samples at each tenth of the flight.
# Pass (exit 0): nothing lost, nothing unacknowledged, no failed write, no keyframe dropped
# before the server saved it (with a server), and flat from LONG_WARMUP_MIN (default 5) minutes
# to the end: agent RSS within LONG_RSS_SLACK_MB (default 20), CPU per frame of the last tenth
# at most LONG_CPU_RATIO (default 1.3) times that of the first tenth after the warm-up, and
# unacknowledged keyframes of the last tenth at most those of the first tenth + 20.
#
# usage: tests/fault_harness/long_flight.sh [OUT_DIR]   (env: BUILD_DIR, LONG_MINUTES=60,
#        LONG_SERVER=1, LONG_RATE=1 (of real time), LONG_AUTOSAVE=20, LONG_SAMPLE_S=30,
#        LONG_DOMAIN=191, LONG_METRICS_PORT=9471, LONG_AGENT_ARGS: more ccm_agent options, e.g.
#        "--config deploy/config/agent-embedded.yaml" for the embedded profile)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BIN="${BUILD_DIR:-$ROOT/build}"
OUT="${1:-$PWD/long-flight-out}"
MINUTES="${LONG_MINUTES:-60}"
RATE="${LONG_RATE:-1}"
AUTOSAVE="${LONG_AUTOSAVE:-20}"
SAMPLE_S="${LONG_SAMPLE_S:-30}"
WARMUP_MIN="${LONG_WARMUP_MIN:-5}"
SLACK_MB="${LONG_RSS_SLACK_MB:-20}"
DOMAIN="${LONG_DOMAIN:-191}"
WITH_SERVER="${LONG_SERVER:-1}"
CPU_RATIO="${LONG_CPU_RATIO:-1.3}"
METRICS_PORT="${LONG_METRICS_PORT:-9471}"
read -r -a EXTRA_AGENT_ARGS <<<"${LONG_AGENT_ARGS:-}"
QOS="$ROOT/qos_profiles/wifi.xml"
for b in server_runtime/ccm_server agent_runtime/ccm_agent tests/sim/ccm_sim; do
  [ -x "$BIN/$b" ] || { echo "missing $BIN/$b: build first (deploy/build.sh)"; exit 2; }
done
rm -rf "$OUT" && mkdir -p "$OUT"
# hall3 with agent 0's loop flown for the whole flight.
flight_s=$((MINUTES * 60))
# shellcheck source=long_hall3.sh
source "$ROOT/tests/fault_harness/long_hall3.sh"
write_long_hall3 "$BIN" "$OUT/hall3.yaml" "$flight_s"
frames=$((flight_s * 20))

server=""
agent_link=(--qos "$QOS" --domain "$DOMAIN" --drain 120)
if [ "$WITH_SERVER" = 1 ]; then
  "$BIN/server_runtime/ccm_server" --qos "$QOS" --domain "$DOMAIN" --map-file "$OUT/stack.ccmmap" \
    --autosave "$AUTOSAVE" --out "$OUT/server" --progress 60 --idle-exit 20 --log-level info >"$OUT/server.log" 2>&1 &
  server=$!
else
  agent_link=(--standalone)
fi
"$BIN/agent_runtime/ccm_agent" "${agent_link[@]}" "${EXTRA_AGENT_ARGS[@]}" --log-level warn --agent-id 1 --metrics "$METRICS_PORT" \
  --sim "$OUT/hall3.yaml" --sim-agent 0 --max-frames "$frames" --rate "$RATE" >"$OUT/agent.log" 2>&1 &
agent=$!
trap 'kill $agent $server 2>/dev/null || true' EXIT
python3 "$ROOT/tests/fault_harness/flight_sampler.py" "$OUT/samples.csv" "$SAMPLE_S" "$agent" \
  "http://127.0.0.1:$METRICS_PORT/metrics" $server
wait $agent && agent_rc=0 || agent_rc=$?
if [ -n "$server" ]; then
  kill -INT $server 2>/dev/null || true
  wait $server || true
fi
trap - EXIT

python3 "$ROOT/tests/fault_harness/long_flight_report.py" "$OUT" "$agent_rc" "$WITH_SERVER" "$WARMUP_MIN" \
  "$SLACK_MB" "$CPU_RATIO"
