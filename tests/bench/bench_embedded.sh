#!/usr/bin/env bash
# The embedded profile's cost (issue 29, docs/deployment.md "Embedded profile"): CPU per frame,
# frames skipped and ATE of `ccm_agent --standalone` with the default config and with
# deploy/config/agent-embedded.yaml, on hall3 (agent 0), New Tsukuba and KITTI 07 (road profile
# under both), paced at the recording's rate x1 and x3 (x3: as a board three times slower than
# this machine; late frames are skipped under both profiles, as a camera would force). Prints
# bench_feature's ORB time of the same run. A benchmark, not a test.
# Usage: tests/bench/bench_embedded.sh [BUILD_DIR]   env: SIM_FRAMES=800, SPEEDS="1 3"
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD="${1:-$ROOT/build}"
AGENT="$BUILD/agent_runtime/ccm_agent"
EVAL="$BUILD/tools/eval/ccm_eval"
FEATURE="$BUILD/tests/slam_core/feature/bench_feature"
DATA="$ROOT/../shared/data"
SPEEDS="${SPEEDS:-1 3}"
OUT="$(mktemp -d)"
trap 'rm -rf "$OUT"' EXIT
for b in "$AGENT" "$EVAL"; do [[ -x "$b" ]] || { echo "bench_embedded: $b missing" >&2; exit 2; }; done
orb="n/a"
[[ -x "$FEATURE" ]] && orb="$("$FEATURE" 2>/dev/null | sed -n 's/.*(CPU \([0-9.]*\)).*/\1/p' | tail -1)"
echo "bench_feature ORB extraction, 752x480: ${orb} ms CPU per frame"
echo
echo "| input | profile | speed | frames | skipped | CPU ms/frame (no input, no set-up) | x ORB | tracked | ATE m | ATE % of path |"
echo "|---|---|---|---|---|---|---|---|---|---|"
embedded="$ROOT/deploy/config/agent-embedded.yaml"
road="$ROOT/deploy/config/agent-road.yaml"
# hall3 is rendered to an EuRoC folder first: rendering in the agent (--sim) costs more than a
# frame period at x3, which a camera does not.
"$BUILD/tests/sim/ccm_sim" --scenario hall3 --agents 0 --seconds "$(( ${SIM_FRAMES:-800} / 20 ))" --out "$OUT/hall3" \
  >/dev/null 2>&1 || { echo "bench_embedded: ccm_sim failed" >&2; exit 2; }
hall3_dir="$(find "$OUT/hall3" -mindepth 1 -maxdepth 1 -type d | head -1)"
# name|base config|ccm_agent input|ground truth for ccm_eval (empty: the agent's --ground-truth)
inputs=("hall3||--dataset $hall3_dir|")
[[ -d "$DATA/ntsd150_euroc" ]] && inputs+=("ntsd150||--dataset $DATA/ntsd150_euroc|")
[[ -d "$DATA/kitti07_first160" ]] && inputs+=("kitti07|$road|--dataset $DATA/kitti07_first160|$DATA/kitti07_first160/poses_07_first160_kitti.txt --kitti-times $DATA/kitti07_first160/times_first160.txt")
for entry in "${inputs[@]}"; do
  IFS='|' read -r name base input gt_spec <<<"$entry"
  read -r -a args <<<"$input"
  for profile in default embedded; do
    cfg="$OUT/$name-$profile.yaml"
    # The embedded keys over the input's base profile (KITTI: the road profile's VO keys too).
    if [[ -n "$base" ]]; then grep -v '^#' "$base" >"$cfg"; else : >"$cfg"; fi
    if [[ $profile == embedded ]]; then
      python3 - "$cfg" "$embedded" <<'PY'
import sys, yaml
cfg, emb = sys.argv[1], sys.argv[2]
base = yaml.safe_load(open(cfg)) or {}
add = yaml.safe_load(open(emb))
vo = dict(base.get("vo") or {}); vo.update(add.pop("vo", {}))
base.update(add); base["vo"] = vo
yaml.safe_dump(base, open(cfg, "w"))
PY
    fi
    for speed in $SPEEDS; do
      tag="$name-$profile-$speed"
      "$AGENT" --standalone --log-level warn --config "$cfg" "${args[@]}" --rate "$speed" --skip-late-frames \
        --trajectory "$OUT/$tag.tum" --ground-truth "$OUT/$tag.gt.tum" >"$OUT/$tag.json" 2>"$OUT/$tag.log" || {
        echo "| $name | $profile | x$speed | failed: $(tail -1 "$OUT/$tag.log") |"; continue; }
      if [[ -n "$gt_spec" ]]; then read -r -a gt_args <<<"$gt_spec"; else gt_args=("$OUT/$tag.gt.tum"); fi
      "$EVAL" --gt "${gt_args[@]}" --est "$OUT/$tag.tum" --json "$OUT/$tag.eval.json" >/dev/null 2>&1 || true
      python3 - "$OUT/$tag.json" "$OUT/$tag.eval.json" "$name" "$profile" "$speed" "$orb" "${gt_args[0]}" <<'PY'
import json, math, sys
s = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])
rows = [[float(x) for x in l.split()] for l in open(sys.argv[7]) if l.strip() and not l.startswith("#")]
# TUM: t x y z ...; KITTI: a 3x4 matrix per row, the translation in columns 3, 7, 11.
gt = [[r[3], r[7], r[11]] if len(r) == 12 else r[1:4] for r in rows]
path = sum(math.dist(a, b) for a, b in zip(gt, gt[1:]))
try:
    rmse = json.load(open(sys.argv[2]))["agents"][0]["ate_m"]["rmse"]
    ate, pct = f"{rmse:.4f}", f"{100 * rmse / path:.2f}"
except Exception:
    ate, pct = "-", "-"
c = s["footprint"]["cpu_ms_per_frame"]
agent = c["total"] - c["input"] - c.get("setup", 0.0)  # per frame, without the one-off set-up
orb = sys.argv[6]
ratio = f"{agent / float(orb):.1f}" if orb not in ("", "n/a") else "-"
print(f"| {sys.argv[3]} | {sys.argv[4]} | x{sys.argv[5]} | {s['frames']} | {s['frames_skipped']} | {agent:.1f} | {ratio} | "
      f"{100.0 * s['tracked'] / max(1, s['frames']):.0f} % | {ate} | {pct} |")
PY
    done
  done
done
