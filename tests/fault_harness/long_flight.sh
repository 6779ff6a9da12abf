#!/usr/bin/env bash
# Long flight (issue 28): one ccm_agent flies hall3's agent-0 loop for LONG_MINUTES (default
# 60) against a ccm_server that saves its map file every LONG_AUTOSAVE s (default 20, the
# packaged value), over qos_profiles/wifi.xml. Every LONG_SAMPLE_S s it samples both
# processes' resident memory (/proc/PID/status VmRSS) into OUT/memory.csv. At the end it
# prints the agent's summary counters and the memory at each tenth of the flight.
# Pass (exit 0): nothing lost, nothing unacknowledged, no failed write, no keyframe dropped
# before the server saved it, and the agent's RSS at the end within LONG_RSS_SLACK_MB
# (default 20) of its RSS at LONG_WARMUP_MIN (default 5) minutes: flat over the flight.
#
# usage: tests/fault_harness/long_flight.sh [OUT_DIR]   (env: BUILD_DIR, LONG_MINUTES=60,
#        LONG_RATE=1 (of real time), LONG_AUTOSAVE=20, LONG_SAMPLE_S=30, LONG_DOMAIN=191)
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

"$BIN/server_runtime/ccm_server" --qos "$QOS" --domain "$DOMAIN" --map-file "$OUT/stack.ccmmap" \
  --autosave "$AUTOSAVE" --out "$OUT/server" --progress 60 --idle-exit 20 --log-level info >"$OUT/server.log" 2>&1 &
server=$!
"$BIN/agent_runtime/ccm_agent" --qos "$QOS" --domain "$DOMAIN" --log-level warn --agent-id 1 \
  --sim "$OUT/hall3.yaml" --sim-agent 0 --max-frames "$frames" --rate "$RATE" --drain 120 >"$OUT/agent.log" 2>&1 &
agent=$!
trap 'kill $agent $server 2>/dev/null || true' EXIT
rss_mb() { awk '/VmRSS/ {printf "%.1f", $2 / 1024}' "/proc/$1/status" 2>/dev/null || echo ""; }
echo "minute,agent_rss_mb,server_rss_mb" >"$OUT/memory.csv"
start=$SECONDS
while kill -0 $agent 2>/dev/null; do
  a=$(rss_mb $agent)
  s=$(rss_mb $server)
  [ -n "$a" ] && echo "$(python3 -c "print(round(($SECONDS - $start) / 60, 2))"),$a,$s" >>"$OUT/memory.csv"
  sleep "$SAMPLE_S"
done
wait $agent && agent_rc=0 || agent_rc=$?
kill -INT $server 2>/dev/null || true
wait $server || true
trap - EXIT

python3 - "$OUT" "$agent_rc" "$WARMUP_MIN" "$SLACK_MB" "$ROOT/tests/fault_harness" <<'PY'
import csv, pathlib, sys
out, agent_rc, warmup, slack = pathlib.Path(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
sys.path.insert(0, sys.argv[5])
from grid_report import last_json_line as last_json  # the fault grid's reader of a summary line
rows = [(float(r["minute"]), float(r["agent_rss_mb"]), float(r["server_rss_mb"] or 0))
        for r in csv.DictReader(open(out / "memory.csv"))]
j = last_json(out / "agent.log") or {}
link = j.get("link", {})
ok = agent_rc == 0
lines = [f"agent exit code {agent_rc}; frames {j.get('frames')}, tracked {j.get('tracked')}, "
         f"keyframes created {j.get('keyframes_created')}"]
keys = ["kfs_sent", "kfs_acked", "kfs_unacked", "kfs_persisted", "kfs_unpersisted", "kfs_resent", "write_failures"]
lines.append("link: " + ", ".join(f"{k} {link.get(k)}" for k in keys))
lines.append(f"keyframes lost {j.get('keyframes_lost')}, dropped before the server saved them "
             f"{j.get('keyframes_dropped_unpersisted')}; peak RSS {j.get('footprint', {}).get('peak_rss_mb')} MB")
ok &= j.get("keyframes_lost") == 0 and link.get("kfs_unacked") == 0 and link.get("write_failures") == 0
ok &= j.get("keyframes_dropped_unpersisted") == 0
lines.append("| minute | agent RSS MB | server RSS MB |")
lines.append("|---|---|---|")
if rows:
    step = max(1, len(rows) // 10)
    for m, a, s in rows[::step] + ([rows[-1]] if (len(rows) - 1) % step else []):
        lines.append(f"| {m:.1f} | {a:.1f} | {s:.1f} |")
    after = [a for m, a, s in rows if m >= warmup]
    if after:
        growth = after[-1] - after[0]
        lines.append(f"agent RSS from minute {warmup:g} to the end: {after[0]:.1f} -> {after[-1]:.1f} MB "
                     f"({growth:+.1f} MB; max {max(after):.1f})")
        ok &= growth <= slack
    else:
        ok = False; lines.append(f"the flight ended before minute {warmup:g}")
else:
    ok = False
lines.append("PASS" if ok else "FAIL")
(out / "long_flight.md").write_text("\n".join(lines) + "\n")
print("\n".join(lines))
sys.exit(0 if ok else 1)
PY
