#!/usr/bin/env bash
# Initialization robustness on a real road (issue 12, docs/vo.md "Initialization on the
# road"): the standalone agent VO on the KITTI 07 excerpt (../shared/data) started at frames
# 0, 5, ..., 30 (the car turns until frame ~40, then drives straight at up to 0.85 m per
# frame). One markdown row per start: frame of initialization, tracked frames, map
# segments, keyframes, ATE (Sim(3)) and ATE / path. A benchmark, not a test (~2 min).
# Usage: tests/bench/kitti_starts.sh [BUILD_DIR] [OUT_DIR] [-- extra ccm_agent args, e.g. --config deploy/config/agent-road.yaml]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD="${1:-$ROOT/build}"
OUT="${2:-$ROOT/kitti-starts-out}"
shift $(( $# > 2 ? 2 : $# )) || true
[[ "${1:-}" == "--" ]] && shift
DATA="$ROOT/../shared/data/kitti07_first160"
[[ -d "$DATA" ]] || { echo "no $DATA: nothing to run"; exit 0; }
echo "| start frame | initialized at | tracked | segments | KFs | ATE | ATE / path |"
echo "|---|---|---|---|---|---|---|"
for start in 0 5 10 15 20 25 30; do
  dir="$OUT/start$start"
  rm -rf "$dir" && mkdir -p "$dir/image_0"
  cp "$DATA/calib.txt" "$dir/"
  for ((i = start; i < 160; ++i)); do
    ln -s "$DATA/image_0/$(printf %06d "$i").png" "$dir/image_0/$(printf %06d $((i - start))).png"
  done
  sed -n "$((start + 1)),160p" "$DATA/times.txt" >"$dir/times.txt"
  sed -n "$((start + 1)),160p" "$DATA/poses_07_first160_kitti.txt" >"$dir/poses.txt"
  "$BUILD/agent_runtime/ccm_agent" --standalone --log-level warn --dataset "$dir" --format kitti \
    --trajectory "$dir/est.txt" "$@" >"$dir/run.json" 2>"$dir/run.log"
  "$BUILD/tools/eval/ccm_eval" --gt "$dir/poses.txt" --kitti-times "$dir/times.txt" --est "$dir/est.txt" \
    --json "$dir/eval.json" >/dev/null 2>&1 || rm -f "$dir/eval.json"
  python3 - "$start" "$dir" <<'EOF2'
import json, math, os, sys
start, d = sys.argv[1:3]
run = json.loads(open(f"{d}/run.json").read().strip().splitlines()[-1])
times = [float(t) for t in open(f"{d}/times.txt")]
est = [float(l.split()[0]) for l in open(f"{d}/est.txt") if l.strip() and not l.startswith("#")] if os.path.exists(f"{d}/est.txt") else []
first = next((i for i, t in enumerate(times) if est and abs(t - est[0]) < 1e-3), None)
poses = [list(map(float, l.split())) for l in open(f"{d}/poses.txt")]
centres = [(p[3], p[7], p[11]) for p in poses]
path = sum(math.dist(a, b) for a, b in zip(centres, centres[1:]))
ate = json.load(open(f"{d}/eval.json"))["agents"][0]["ate_m"]["rmse"] if os.path.exists(f"{d}/eval.json") else None
ate_s = f"{ate:.3f} m | {100 * ate / path:.2f} %" if ate is not None else "- | -"
print(f"| {start} | {first if first is not None else 'never'} | {run['tracked']}/{run['frames']} | "
      f"{run['segments']} | {run['keyframes_created']} | {ate_s} |")
EOF2
done
