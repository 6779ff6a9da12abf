#!/usr/bin/env bash
# Long mission (issue 30, item 5; a benchmark, not a test): MISSION_AGENTS live ccm_agent
# (default 3: hall3's agents 0-2, each flying its loop again and again) against one
# ccm_server over qos_profiles/wifi.xml for MISSION_MINUTES of flight (default 30) at
# MISSION_RATE of real time (default 0.5: three VOs and the server share 2 cores, so 30
# minutes of flight take an hour). The server writes a row per MISSION_SAMPLE_S to
# OUT/server/timeline.jsonl (server_runtime/mission_timeline.h); at the end this prints, at
# each tenth of the mission: server RSS, keyframes (full and anchors) and points, the
# keyframes' registration + mapping time (median / p95 of that window), the longest global
# BA of the window and its size, the deepest agent queue; then each agent's link summary
# (keyframes acknowledged, lost, send -> ack latency) and the accuracy at the end (each
# agent's per-frame trajectory, and the server map's keyframes, against ground truth). Print bench_feature's ORB time beside
# the numbers (the machine's speed varies 2x from day to day).
#
# usage: tests/bench/long_mission.sh [OUT_DIR]   (env: BUILD_DIR, MISSION_MINUTES=30,
#        MISSION_AGENTS=3, MISSION_RATE=0.5, MISSION_SAMPLE_S=30, MISSION_DOMAIN=193,
#        MISSION_DROP=0 (incoming datagrams each process loses), SERVER_ARGS)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BIN="${BUILD_DIR:-$ROOT/build}"
OUT="${1:-$PWD/long-mission-out}"
MINUTES="${MISSION_MINUTES:-30}"
AGENTS="${MISSION_AGENTS:-3}"
RATE="${MISSION_RATE:-0.5}"
SAMPLE_S="${MISSION_SAMPLE_S:-30}"
DOMAIN="${MISSION_DOMAIN:-193}"
DROP="${MISSION_DROP:-0}"
QOS="$ROOT/qos_profiles/wifi.xml"
for b in server_runtime/ccm_server agent_runtime/ccm_agent tests/sim/ccm_sim; do
  [ -x "$BIN/$b" ] || { echo "missing $BIN/$b: build first (deploy/build.sh)"; exit 2; }
done
[ "$AGENTS" -ge 1 ] && [ "$AGENTS" -le 3 ] || { echo "MISSION_AGENTS must be 1-3 (hall3 has three agents)"; exit 2; }
rm -rf "$OUT" && mkdir -p "$OUT"
if [ -x "$BIN/tests/slam_core/feature/bench_feature" ]; then
  echo "bench_feature (ORB, 752x480): $("$BIN/tests/slam_core/feature/bench_feature" 2>/dev/null |
    grep 'extract ms/frame' | tail -1 | sed 's/^ *//')" | tee "$OUT/bench_feature.txt"
fi
# hall3 with every agent's loop flown for the whole mission.
flight_s=$((MINUTES * 60))
# shellcheck source=../fault_harness/long_hall3.sh
source "$ROOT/tests/fault_harness/long_hall3.sh"
write_long_hall3 "$BIN" "$OUT/hall3.yaml" "$flight_s"
frames=$((flight_s * 20))
common=(--qos "$QOS" --domain "$DOMAIN" --drop "$DROP" --delay-ms 20)
# shellcheck disable=SC2086
"$BIN/server_runtime/ccm_server" "${common[@]}" --out "$OUT/server" --progress "$SAMPLE_S" --idle-exit 20 \
  --log-level info ${SERVER_ARGS:-} >"$OUT/server.log" 2>&1 &
server=$!
pids=()
for a in $(seq 1 "$AGENTS"); do
  "$BIN/agent_runtime/ccm_agent" "${common[@]}" --log-level warn --agent-id "$a" --sim "$OUT/hall3.yaml" \
    --sim-agent $((a - 1)) --max-frames "$frames" --rate "$RATE" --drain 120 \
    --ground-truth "$OUT/agent${a}_ground_truth.tum" --trajectory "$OUT/agent${a}_frames.tum" \
    --keyframes "$OUT/agent${a}_keyframes.tum" >"$OUT/agent$a.log" 2>&1 &
  pids+=($!)
done
trap 'kill "${pids[@]}" $server 2>/dev/null || true' EXIT
status=0
for p in "${pids[@]}"; do wait "$p" || status=1; done
wait $server || status=1
trap - EXIT
# Accuracy at the end: each agent's own per-frame trajectory (its VO, every lap), and the
# server map's keyframes of every agent under one alignment.
own=() map=()
for a in $(seq 1 "$AGENTS"); do
  own+=(--gt "$OUT/agent${a}_ground_truth.tum" --est "$OUT/agent${a}_frames.tum" --name "agent$a")
  map+=(--gt "$OUT/agent${a}_ground_truth.tum" --est "$OUT/server/agent${a}_keyframes.tum" --name "agent$a")
done
"$BIN/tools/eval/ccm_eval" "${own[@]}" >"$OUT/eval_own_frames.txt" 2>&1 || status=1
"$BIN/tools/eval/ccm_eval" "${map[@]}" --plot "$OUT/server_map_ate.png" >"$OUT/eval_server_map.txt" 2>&1 || status=1

python3 - "$OUT" "$AGENTS" "$status" "$ROOT/tests/fault_harness" "$RATE" <<'PY'
import json, pathlib, sys
out, agents, status, rate = pathlib.Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[5])
sys.path.insert(0, sys.argv[4])
from grid_report import last_json_line as last_json  # the fault grid's reader of a summary line
rows = [json.loads(l) for l in open(out / "server" / "timeline.jsonl") if l.strip()]
lines = ["| minute (of flight) | server RSS MB | keyframes (+ anchors) | points | keyframe ms median / p95 | longest global BA s (keyframes) | deepest queue |",
         "|---|---|---|---|---|---|---|"]
if rows:
    step = max(1, len(rows) // 10)
    picked = rows[::step] + ([rows[-1]] if (len(rows) - 1) % step else [])
    for i, r in enumerate(picked):
        # The BA column covers every row since the previous printed one.
        lo = rows.index(picked[i - 1]) + 1 if i else 0
        hi = rows.index(r) + 1
        ba = max(rows[lo:hi], key=lambda x: x["global_ba_s_max"])
        lines.append(f"| {r['t_s'] / 60:.1f} ({r['t_s'] * rate / 60:.1f}) | {r['rss_mb']:.0f} | {r['keyframes']} (+{r['anchored']}) | "
                     f"{r['map_points']} | {r['keyframe_ms_median']:.0f} / {r['keyframe_ms_p95']:.0f} | "
                     f"{ba['global_ba_s_max']:.2f} ({ba['global_ba_keyframes']}) | "
                     f"{max(x['deepest_queue'] for x in rows[lo:hi])} |")
    last = rows[-1]
    lines.append(f"maps {last['maps']}, fusions {last['fusions']}, loops {last['loops']}, global BAs "
                 f"{last['global_bas']}, keyframes removed as redundant {last['keyframes_removed']}")
for a in range(1, agents + 1):
    j = last_json(out / f"agent{a}.log") or {}
    link = j.get("link", {})
    lines.append(f"agent {a}: frames {j.get('frames')}, tracked {j.get('tracked')}, keyframes created "
                 f"{j.get('keyframes_created')}, sent {link.get('kfs_sent')} ({link.get('kfs_sent_as_anchors')} as anchors), "
                 f"acked {link.get('kfs_acked')}, unacked {link.get('kfs_unacked')}, lost {j.get('keyframes_lost')}; "
                 f"send -> ack median {link.get('ack_ms_median', 0):.0f} ms, p95 {link.get('ack_ms_p95', 0):.0f} ms, "
                 f"max {link.get('ack_ms_max', 0):.0f} ms; peak RSS {j.get('footprint', {}).get('peak_rss_mb', 0):.0f} MB")
for name in ("eval_own_frames", "eval_server_map"):
    text = (out / f"{name}.txt").read_text() if (out / f"{name}.txt").exists() else ""
    ate = [l for l in text.splitlines() if l.startswith(("agent", "JOINT"))][:agents + 1]
    lines.append(("each agent's own per-frame trajectory (ATE m: rmse is column 6)" if name == "eval_own_frames"
                  else "every agent's keyframes in the server map (joint rmse: last column)") + ":")
    lines += ["    " + l for l in ate]
lines.append("exit codes: all 0" if status == 0 else "a process failed (see the logs)")
(out / "long_mission.md").write_text("\n".join(lines) + "\n")
print("\n".join(lines))
sys.exit(status)
PY
