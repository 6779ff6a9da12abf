#!/usr/bin/env bash
# The fleet step of the ThreadSanitizer job (deploy/run-sanitizer-tests.sh tsan): ccm_server
# and ccm_fleet of build tree BUILD_DIR (both under TSan) over DDS on a private domain, every
# process losing 10 % of its incoming datagrams: six recorded agents (the hall3 recording
# twice, so fusions, loops, map sharing and, with TSan's slowdown, hundreds of resends) against
# a server that autosaves every 5 s and serves its map view to a polling client. Covers what
# the two-agent live run does not: ServerComm and the back-end's handler threads with six
# agents at once, and AgentComm's comm threads in one process. Fails on any ThreadSanitizer
# report (OUT_DIR/tsan.<pid>), a failed process or a keyframe left unacknowledged.
# Usage: tsan-fleet-run.sh BUILD_DIR OUT_DIR RECORDING [SPEED]
set -euo pipefail
B="$1"
OUT="$2"
REC="$3"
SPEED="${4:-0.5}"
DOMAIN="${SAN_FLEET_DOMAIN:-188}"
PORT="${SAN_FLEET_PORT:-18188}"
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ -f "$REC" ] || { echo "no recording $REC (server_test's ServerScenario.Hall3 writes it in a normal build)" >&2; exit 2; }
rm -rf "$OUT"
mkdir -p "$OUT"
export TSAN_OPTIONS="${TSAN_OPTIONS:-}:log_path=$OUT/tsan:exitcode=66"
link=(--qos "$ROOT/qos_profiles/wifi.xml" --domain "$DOMAIN" --drop 0.1 --delay-ms 50 --log-level warn)
trap 'kill $(jobs -p) 2>/dev/null || true' EXIT
"$B/server_runtime/ccm_server" --idle-exit 8 --duration 1800 --out "$OUT/server" --map-file "$OUT/map.stack" \
  --autosave 5 --http "$PORT" "${link[@]}" >"$OUT/server.log" 2>&1 &
server=$!
sleep 3
( while kill -0 "$server" 2>/dev/null; do
    curl -s -m 5 "http://127.0.0.1:$PORT/api/status" >/dev/null || true
    curl -s -m 5 "http://127.0.0.1:$PORT/api/map?since=0" >/dev/null || true
    sleep 2
  done ) &
status=0
"$B/tools/fleet/ccm_fleet" --recording "$REC" --recording "$REC" --speed "$SPEED" --drain 300 --out "$OUT/fleet" \
  "${link[@]}" >"$OUT/fleet.log" 2>&1 || { echo "ccm_fleet exited $? (see $OUT/fleet.log)"; status=1; }
wait "$server" || { echo "ccm_server exited $? (see $OUT/server.log)"; status=1; }
trap - EXIT
"$(dirname "${BASH_SOURCE[0]}")/tsan-reports.sh" "$OUT" || status=1
echo "fleet run: $(tail -1 "$OUT/fleet.log" | grep -o '"kfs_acked":[0-9]*,"kfs_resent":[0-9]*,"kfs_sent":[0-9]*,"kfs_unacked":[0-9]*' || echo 'no fleet summary'); exit $status"
exit "$status"
