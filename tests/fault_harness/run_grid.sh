#!/usr/bin/env bash
# The network-fault grid of CCM-SLAM's evaluation (issue 11): 1, 2, 3 agents x {perfect,
# delay 0.5 s, P_loss 0.2, P_loss 0.5}. Each cell runs ccm_server and the agents as separate
# processes on the simulator's hall3 scenario (sim agents 0..n-1; 1 and 2 for two agents) over qos_profiles/wifi.xml; the fault applies
# per direction in every receiving process (the in-process fault transport: --drop,
# --delay-ms), so agent -> server and server -> agent traffic both see it. Per cell: traffic
# per agent both ways [MB/s of flight], keyframes lost (left the agent's N + B buffer
# unacknowledged) and unacknowledged at the end, fusions, collaborative ATE of all agents'
# server keyframes (one Sim(3), ccm_eval). Writes OUT/grid.md and OUT/grid.png.
#
# usage: tests/fault_harness/run_grid.sh [OUT_DIR]    (env: BUILD_DIR, GRID_FRAMES, GRID_RATE,
#        GRID_AGENTS="1 2 3", GRID_CONDITIONS="perfect delay loss20 loss50", GRID_N=50)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BIN="${BUILD_DIR:-$ROOT/build}"
OUT="${1:-$PWD/grid-out}"
FRAMES="${GRID_FRAMES:-800}"
RATE="${GRID_RATE:-0.5}"
AGENTS="${GRID_AGENTS:-1 2 3}"
CONDITIONS="${GRID_CONDITIONS:-perfect delay loss20 loss50}"
N="${GRID_N:-50}"
QOS="$ROOT/qos_profiles/wifi.xml"
mkdir -p "$OUT"
for b in server_runtime/ccm_server agent_runtime/ccm_agent tools/eval/ccm_eval; do
  [ -x "$BIN/$b" ] || { echo "missing $BIN/$b: build first (deploy/build.sh)"; exit 2; }
done
fault_args() {
  case "$1" in
    perfect) echo "--drop 0 --delay-ms 0" ;;
    delay) echo "--drop 0 --delay-ms 500" ;;
    loss20) echo "--drop 0.2 --delay-ms 0" ;;
    loss50) echo "--drop 0.5 --delay-ms 0" ;;
    *) echo "unknown condition $1" >&2; exit 2 ;;
  esac
}
domain=60
for n in $AGENTS; do
  for cond in $CONDITIONS; do
    cell="$OUT/${n}agents_$cond"
    rm -rf "$cell" && mkdir -p "$cell"
    domain=$((domain + 1))
    read -r -a faults <<<"$(fault_args "$cond")"
    common=(--qos "$QOS" --domain "$domain" "${faults[@]}" --log-level warn)
    echo "[grid] $n agent(s), $cond: ${faults[*]}"
    "$BIN/server_runtime/ccm_server" "${common[@]}" --idle-exit 5 --duration 1200 --out "$cell/server" \
      >"$cell/server.log" 2>&1 &
    server_pid=$!
    pids=()
    for ((a = 1; a <= n; a++)); do
      # Two agents fly hall3's sim agents 1 and 2 (a ~5 s overlap at 19-24 s, as the
      # Collaboration test); sim agents 0 and 1 overlap for only 2-3 s in their first 60 s,
      # so a 2-agent cell on them could show 0 fusions by chance.
      sim_agent=$((n == 2 ? a : a - 1))
      cfg="$cell/agent$a.yaml"
      printf 'max_keyframes: %s\n' "$N" >"$cfg"
      "$BIN/agent_runtime/ccm_agent" -c "$cfg" "${common[@]}" --agent-id "$a" --sim hall3 --sim-agent "$sim_agent" \
        --max-frames "$FRAMES" --rate "$RATE" --drain 120 --ground-truth "$cell/gt$a.tum" >"$cell/agent$a.log" 2>&1 &
      pids+=($!)
    done
    for p in "${pids[@]}"; do wait "$p" || echo "[grid]   an agent exited with an error (see $cell)"; done
    wait "$server_pid" || echo "[grid]   the server exited with an error (see $cell/server.log)"
    eval_args=()
    for ((a = 1; a <= n; a++)); do eval_args+=(--gt "$cell/gt$a.tum" --est "$cell/server/agent${a}_keyframes.tum"); done
    "$BIN/tools/eval/ccm_eval" "${eval_args[@]}" --json "$cell/eval.json" >"$cell/eval.txt" 2>&1 || true
  done
done
PY=/usr/bin/python3
if ! $PY -c "import matplotlib" 2>/dev/null; then
  echo "[grid] installing python3-matplotlib (Debian) for the plot"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO=sudo
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends python3-matplotlib >/dev/null || true
fi
$PY "$ROOT/tests/fault_harness/grid_report.py" "$OUT" "$AGENTS" "$CONDITIONS"
