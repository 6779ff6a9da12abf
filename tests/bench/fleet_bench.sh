#!/bin/bash
# Team-scale benchmark (issue 30; a benchmark, not a test: ~3-6 min per team size): for each
# team size N, a real ccm_server and ccm_fleet playing the first N agents of the given
# recordings over DDS (wifi.xml, every process losing LOSS of its incoming datagrams), then
# the same N streams through ccm_replay's deterministic engine (ccm_fleet --offline) as the
# yardstick. Prints one table row per N: keyframes, lost, resends, ack latency (send -> the
# server's acknowledgement of the processed keyframe: queueing + registration + the link),
# seconds from the last batch to the last ack, traffic per agent, the server's CPU and peak
# RSS, the deepest per-agent queue seen, maps and joint ATE live vs offline.
#
#   tests/bench/fleet_bench.sh BUILD OUT REC.ccmrec [REC2.ccmrec ...]
#   SIZES="4 8 16 24" LOSS=0.1 SPEED=1 tests/bench/fleet_bench.sh build /tmp/fleet-bench a.ccmrec b.ccmrec
#   OFFLINE_FROM=/tmp/fleet-bench LOSS=0 ... : live runs only, offline numbers from an earlier run
#
# Recordings: ccm_replay --record FILE, or bench_fusion --seeds S --record DIR (gen-S.ccmrec).
# Agents are taken in recording order, so a size that ends inside a recording plays part of
# its team. Print bench_feature's ORB time beside the numbers (the machine's speed varies).
set -euo pipefail
BUILD=$(realpath "${1:?usage: fleet_bench.sh BUILD OUT REC...}")
OUT=${2:?usage: fleet_bench.sh BUILD OUT REC...}
shift 2
[ $# -ge 1 ] || { echo "give at least one recording" >&2; exit 2; }
SIZES=${SIZES:-"4 8 16"}
LOSS=${LOSS:-0.1}
SPEED=${SPEED:-1}
DOMAIN=${DOMAIN:-121}
QOS=$(dirname "$0")/../../qos_profiles/wifi.xml
SERVER=$BUILD/server_runtime/ccm_server
FLEET=$BUILD/tools/fleet/ccm_fleet
for f in "$SERVER" "$FLEET"; do [ -x "$f" ] || { echo "missing $f (build it first)" >&2; exit 2; }; done
RECS=()
for r in "$@"; do RECS+=(--recording "$(realpath "$r")"); done
mkdir -p "$OUT"

BENCH_FEATURE=$BUILD/tests/slam_core/feature/bench_feature
if [ -x "$BENCH_FEATURE" ]; then
  echo "bench_feature (ORB, 752x480): $("$BENCH_FEATURE" 2>/dev/null | grep 'extract ms/frame' | tail -1 | sed 's/^ *//')"
fi
ROWS=$OUT/rows.txt
: > "$ROWS"
for N in $SIZES; do
  D=$OUT/n$N
  rm -rf "$D" && mkdir -p "$D"
  # ccm_server refuses agents beyond max_agents (default 16).
  printf 'max_agents: %d\n' "$N" > "$D/server.yaml"
  echo "== $N agents: live (loss $LOSS, speed $SPEED)"
  /usr/bin/time -v -o "$D/server.time" "$SERVER" -c "$D/server.yaml" --domain "$DOMAIN" --qos "$QOS" --drop "$LOSS" --delay-ms 20 \
    --idle-exit 10 --duration 3600 --progress 2 --save-map "$D/map.ccmmap" --out "$D/server" > "$D/server.log" 2>&1 &
  SERVER_PID=$!
  "$FLEET" --domain "$DOMAIN" --qos "$QOS" --drop "$LOSS" --delay-ms 20 "${RECS[@]}" --agents "$N" --speed "$SPEED" \
    --drain 120 --progress 10 --out "$D/fleet" > "$D/fleet.log" 2>&1 || echo "  fleet exit $? (keyframes unacknowledged?)"
  wait "$SERVER_PID" || echo "  server exit $?"
  "$FLEET" "${RECS[@]}" --agents "$N" --score "$D/map.ccmmap" --out "$D/fleet" > "$D/score.log" 2>&1
  OFF=$D/fleet/offline
  if [ -n "${OFFLINE_FROM:-}" ]; then
    OFF=$OFFLINE_FROM/n$N/fleet/offline
  else
    echo "== $N agents: offline"
    "$FLEET" "${RECS[@]}" --agents "$N" --offline --out "$D/fleet" > "$D/offline.log" 2>&1
  fi
  python3 - "$D" "$N" "$OFF" >> "$ROWS" <<'EOF'
import json, re, sys
d, n, off_dir = sys.argv[1], sys.argv[2], sys.argv[3]
fleet = json.load(open(f"{d}/fleet/fleet.json"))["totals"]
live = json.load(open(f"{d}/fleet/score/summary.json"))
off = json.load(open(f"{off_dir}/summary.json"))
log = open(f"{d}/server.log").read()
queue = max([int(q) for q in re.findall(r"queue (\d+)", log)] or [0])
tm = open(f"{d}/server.time").read()
cpu = sum(float(x) for x in re.findall(r"(?:User|System) time \(seconds\): ([\d.]+)", tm))
rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", tm).group(1)) / 1024
def joint(s): return s["accuracy"]["collaborative_ate_m"]["rmse"]
ratio = joint(live) / joint(off) if joint(off) > 0 else float("nan")
print(f"| {n} | {fleet['kfs_sent']} | {fleet['kfs_unacked']} | {fleet['kfs_resent']} | "
      f"{fleet['ack_ms_median_of_agents']:.0f} / {fleet['ack_ms_p95_worst_agent']:.0f} | {fleet['drain_s']:.1f} | "
      f"{fleet['up_mb_per_s_per_agent']:.3f} / {fleet['down_mb_per_s_per_agent']:.3f} | {cpu:.0f} s, {rss:.0f} MB | "
      f"{queue} | {len(live['maps'])} / {len(off['maps'])} | {joint(live):.4f} / {joint(off):.4f} ({ratio:.2f}x) |")
EOF
  tail -1 "$ROWS"
done
echo
echo "| agents | KFs sent | unacked | resent | ack ms median / worst p95 | drain s | MB/s per agent up / down | server CPU, peak RSS | max agent queue | maps live / offline | joint ATE m live / offline (largest map) |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
cat "$ROWS"
