#!/usr/bin/env bash
# The live step of the ThreadSanitizer job (deploy/run-sanitizer-tests.sh tsan): the real
# processes of build tree BUILD_DIR over DDS on a private domain. ccm_server (ServerComm's
# comm thread and the DDS listeners, BackendRunner's stage threads, the map view's HTTP and
# snapshot threads, autosave every 2 s from the main thread) and two ccm_agent (tracking,
# AgentVo's mapping thread, AgentComm's comm thread) on FRAMES simulator frames of hall3
# each, while a client polls the map view. Fails on any ThreadSanitizer report (each process
# writes OUT_DIR/tsan.<pid>) or any process that fails.
# Usage: tsan-live-run.sh BUILD_DIR OUT_DIR [FRAMES]
set -euo pipefail
B="$1"
OUT="$2"
FRAMES="${3:-160}"
DOMAIN="${SAN_LIVE_DOMAIN:-187}"
PORT="${SAN_LIVE_PORT:-18187}"
rm -rf "$OUT"
mkdir -p "$OUT"
export TSAN_OPTIONS="${TSAN_OPTIONS:-}:log_path=$OUT/tsan:exitcode=66"
trap 'kill $(jobs -p) 2>/dev/null || true' EXIT
"$B/server_runtime/ccm_server" --domain "$DOMAIN" --http "$PORT" --map-file "$OUT/map.stack" --autosave 2 \
  --idle-exit 15 --duration 1800 --progress 10 --no-final-ba >"$OUT/server.log" 2>&1 &
server=$!
agents=()
for id in 1 2; do
  # A tenth of real time: under TSan the VO runs at a few frames per second.
  "$B/agent_runtime/ccm_agent" --domain "$DOMAIN" --agent-id "$id" --sim hall3 --sim-agent $((id - 1)) \
    --max-frames "$FRAMES" --rate 0.1 --drain 30 >"$OUT/agent$id.log" 2>&1 &
  agents+=($!)
done
polls=0
while kill -0 "${agents[@]}" 2>/dev/null; do
  sleep 2
  if python3 - "$PORT" <<'EOF'
import sys, urllib.request
for path in ("/api/status", "/api/map?since=0", "/api/events"):
    urllib.request.urlopen(f"http://127.0.0.1:{sys.argv[1]}{path}", timeout=5).read()
EOF
  then
    polls=$((polls + 1))
  fi
done
status=0
for i in 0 1; do
  wait "${agents[$i]}" || { echo "agent $((i + 1)) exited $? (see $OUT/agent$((i + 1)).log)"; status=1; }
done
wait "$server" || { echo "ccm_server exited $? (see $OUT/server.log)"; status=1; }
trap - EXIT
"$(dirname "${BASH_SOURCE[0]}")/tsan-reports.sh" "$OUT" || status=1
# The agents' JSON summaries: keyframes made and lost (sent but never acknowledged).
kfs=$(grep -a -h -o '"keyframes_created":[0-9]*\|"keyframes_lost":[0-9]*' "$OUT"/agent*.log | tr -d '"' | tr '\n' ' ' || true)
echo "live run: $FRAMES frames per agent, $polls map view polls, ${kfs:-no agent summary found}; exit $status"
exit "$status"
