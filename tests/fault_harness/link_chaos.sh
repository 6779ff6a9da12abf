#!/usr/bin/env bash
# Link chaos (issue 28): the ground station's link cut for a minute and its bandwidth capped,
# with two agents flying hall3 (sim agents 1 and 2, which overlap and fuse) at real time over
# qos_profiles/wifi.xml. The faults act in the server's process (runtime_common's fault
# transport: --cut-at/--cut-s drop everything it sends and receives, --rate-cap queues what
# it receives behind a link of that many kB/s with a 0.5 s buffer and drops the rest, as an
# access point every agent shares). Cells (LINK_CELLS):
#   none       no fault (the reference)
#   cut60      the link down from 5 s to 65 s of the flight, the agents' default B (50)
#   cut60b250  the same with buffer_keyframes 250: B sized for the minute (docs/protocol.md)
#   cap200 cap100 cap50   uplink of both agents together capped at 200 / 100 / 50 kB/s
#   cap200t cap100t cap50t   the same with wifi.xml tuned to the link: each agent's new-data
#              throughputController at 40 % of the cap (two agents: 80 %), in 100-ms periods
# Per cell and agent: keyframes sent / acknowledged / unacknowledged / lost, dropped before a
# save, the longest and p95 wait for an ack, the agent's exit code; per cell: fusions, maps and
# the collaborative ATE of the server's map (ccm_eval, one Sim(3)). Writes OUT/link_chaos.md.
# The ctest Chaos.* asserts the short cases (a one-agent cut of 60 s, autosaves refused).
#
# usage: tests/fault_harness/link_chaos.sh [OUT_DIR]   (env: BUILD_DIR, LINK_FRAMES=1400,
#        LINK_CELLS="none cut60 cut60b250 cap200 cap100 cap50 cap200t cap100t cap50t")
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BIN="${BUILD_DIR:-$ROOT/build}"
OUT="${1:-$PWD/link-chaos-out}"
FRAMES="${LINK_FRAMES:-1400}"
CELLS="${LINK_CELLS:-none cut60 cut60b250 cap200 cap100 cap50 cap200t cap100t cap50t}"
QOS="$ROOT/qos_profiles/wifi.xml"
for b in server_runtime/ccm_server agent_runtime/ccm_agent tools/eval/ccm_eval; do
  [ -x "$BIN/$b" ] || { echo "missing $BIN/$b: build first (deploy/build.sh)"; exit 2; }
done
mkdir -p "$OUT"
domain=120
for cell in $CELLS; do
  dir="$OUT/$cell"
  rm -rf "$dir" && mkdir -p "$dir"
  domain=$((domain + 1))
  server_fault=() buffer=50 qos="$QOS"
  case "$cell" in
    none) ;;
    cut60) server_fault=(--cut-at 5 --cut-s 60) ;;
    cut60b250) server_fault=(--cut-at 5 --cut-s 60) buffer=250 ;;
    cap*t)
      kb="${cell#cap}" && kb="${kb%t}"
      server_fault=(--rate-cap "$kb")
      # The agents' new-data writers (the first throughputController in wifi.xml; the second
      # is the server's) limited to 40 % of the link each.
      qos="$dir/wifi-tuned.xml"
      python3 - "$QOS" "$qos" "$kb" <<'PY'
import sys
src, dst, kb = sys.argv[1], sys.argv[2], float(sys.argv[3])
text = open(src).read()
old = "<bytesPerPeriod>50000</bytesPerPeriod>\n                <periodMillisecs>50</periodMillisecs>"
assert old in text, "wifi.xml's new-data throughputController changed: update link_chaos.sh"
new = f"<bytesPerPeriod>{int(kb * 1000 * 0.4 / 10)}</bytesPerPeriod>\n                <periodMillisecs>100</periodMillisecs>"
open(dst, "w").write(text.replace(old, new, 1))
PY
      ;;
    cap*) server_fault=(--rate-cap "${cell#cap}") ;;
    *) echo "unknown cell $cell"; exit 2 ;;
  esac
  echo "[link-chaos] $cell: ${server_fault[*]:-no fault}, buffer_keyframes $buffer, QoS $qos"
  "$BIN/server_runtime/ccm_server" --qos "$qos" --domain "$domain" "${server_fault[@]}" --duration 900 \
    --out "$dir/server" --progress 10 --log-level info >"$dir/server.log" 2>&1 &
  server_pid=$!
  pids=()
  for a in 1 2; do
    printf 'buffer_keyframes: %s\n' "$buffer" >"$dir/agent$a.yaml"
    "$BIN/agent_runtime/ccm_agent" -c "$dir/agent$a.yaml" --qos "$qos" --domain "$domain" --agent-id "$a" \
      --sim hall3 --sim-agent "$a" --max-frames "$FRAMES" --rate realtime --drain 120 \
      --ground-truth "$dir/gt$a.tum" --log-level warn >"$dir/agent$a.log" 2>&1 &
    pids+=($!)
  done
  for a in 1 2; do
    code=0
    wait "${pids[$((a - 1))]}" || code=$?
    echo "$code" >"$dir/agent$a.exit"
  done
  # A clean stop once both agents are done (an idle exit would also fire during a cut).
  kill -TERM "$server_pid" 2>/dev/null || true
  wait "$server_pid" || echo "[link-chaos]   the server exited with an error (see $dir/server.log)"
  "$BIN/tools/eval/ccm_eval" --gt "$dir/gt1.tum" --est "$dir/server/agent1_keyframes.tum" --gt "$dir/gt2.tum" \
    --est "$dir/server/agent2_keyframes.tum" --json "$dir/eval.json" >"$dir/eval.txt" 2>&1 || true
done
python3 - "$OUT" "$ROOT/tests/fault_harness" "$CELLS" <<'PY'
import json, os, sys
out, here, cells = sys.argv[1], sys.argv[2], sys.argv[3].split()
sys.path.insert(0, here)
from grid_report import last_json_line  # the fault grid's reader of a summary line

def load(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None

rows = ["| cell | agent | exit | KFs sent | acked | unacked | lost | dropped before a save | ack wait max / p95 [s] |"
        " fusions | maps | collaborative ATE [m] |", "|" + "---|" * 12]
for cell in cells:
    d = f"{out}/{cell}"
    summary = load(f"{d}/server/summary.json") or {}
    ev = load(f"{d}/eval.json") or {}
    joint = ev.get("joint", {}).get("ate_m", {}).get("rmse")
    for a in (1, 2):
        j = last_json_line(f"{d}/agent{a}.log") or {}
        link = j.get("link", {})
        code = open(f"{d}/agent{a}.exit").read().strip() if os.path.exists(f"{d}/agent{a}.exit") else "?"
        wait = (f"{link['ack_ms_max'] / 1000:.1f} / {link['ack_ms_p95'] / 1000:.1f}" if "ack_ms_max" in link else "-")
        first = a == 1
        rows.append(f"| {cell if first else ''} | {a} | {code} | {link.get('kfs_sent', '-')} | {link.get('kfs_acked', '-')} | "
                    f"{link.get('kfs_unacked', '-')} | {j.get('keyframes_lost', '-')} | "
                    f"{j.get('keyframes_dropped_unpersisted', '-')} | {wait} | "
                    f"{summary.get('fusions', '-') if first else ''} | {len(summary.get('maps', [])) if first else ''} | "
                    f"{(f'{joint:.4f}' if joint is not None else '-') if first else ''} |")
text = "\n".join(rows) + "\n"
open(f"{out}/link_chaos.md", "w").write(text)
print(text)
PY
