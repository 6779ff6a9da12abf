#!/usr/bin/env bash
# Keyframe economy table (issue 12, docs/vo.md): runs the standalone agent VO on hall3's three
# flights, the KITTI 07 excerpt and the New Tsukuba excerpt (../shared/data; skipped when
# absent) and prints one markdown row per run: keyframes created per 100 frames, tracked
# fraction, ATE (Sim(3), % of path), tracking median/p95 and mapping ms per keyframe.
# Usage: tests/bench/vo_table.sh [BUILD_DIR] [OUT_DIR] [-- extra ccm_agent args...]
# Takes ~5 min on 2 cores (hall3 dominates). A benchmark, not a test. SIM=FILE flies another
# scenario YAML instead of hall3 (e.g. hall3 with another seed: ccm_sim --dump hall3), SKIP_HALL3,
# SKIP_ROAD, SKIP_REAL and HALL3_AGENTS="0 2" trim the runs.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD="${1:-$ROOT/build}"
OUT="${2:-$ROOT/vo-table-out}"
shift $(( $# > 2 ? 2 : $# )) || true
[[ "${1:-}" == "--" ]] && shift
EXTRA=("$@")
AGENT="$BUILD/agent_runtime/ccm_agent"
EVAL="$BUILD/tools/eval/ccm_eval"
DATA="$ROOT/../shared/data"
mkdir -p "$OUT"

run() {  # name, agent args...; env GT_KITTI=poses file and KITTI_TIMES for KITTI excerpts
  local name="$1"; shift
  local gt="$OUT/$name.gt.txt"
  "$AGENT" --standalone --log-level warn --trajectory "$OUT/$name.est.txt" --ground-truth "$OUT/$name.gt.txt" \
    "$@" "${EXTRA[@]}" >"$OUT/$name.json" 2>"$OUT/$name.log"
  local eval_gt=(--gt "$gt")
  if [[ -n "${GT_KITTI:-}" ]]; then
    python3 - "$GT_KITTI" "$KITTI_TIMES" "$gt" <<'EOF2'
import sys
poses, times, out = sys.argv[1:4]
with open(out, "w") as f:
    for p, t in zip(open(poses), open(times)):
        v = list(map(float, p.split()))
        f.write(f"{float(t):.9f} {v[3]} {v[7]} {v[11]} 0 0 0 1\n")
EOF2
    eval_gt=(--gt "$GT_KITTI" --kitti-times "$KITTI_TIMES")
  fi
  "$EVAL" "${eval_gt[@]}" --est "$OUT/$name.est.txt" --json "$OUT/$name.eval.json" >/dev/null
  python3 - "$name" "$OUT/$name.json" "$OUT/$name.eval.json" "$gt" <<'EOF2'
import json, math, sys
name, run_path, eval_path, gt_path = sys.argv[1:5]
run = json.loads(open(run_path).read().strip().splitlines()[-1])
ate = json.load(open(eval_path))["agents"][0]["ate_m"]["rmse"]
pts = [tuple(map(float, l.split()[1:4])) for l in open(gt_path) if l.strip() and not l.startswith("#")]
path = sum(math.dist(a, b) for a, b in zip(pts, pts[1:]))
frames = run["frames"]
print(f"| {name} | {frames} | {100.0 * run['keyframes_created'] / frames:.1f} | "
      f"{100.0 * run['tracked'] / frames:.1f}% | {ate:.4f} m | {100.0 * ate / path:.3f}% | "
      f"{run['tracking_ms_median']:.1f} / {run['tracking_ms_p95']:.1f} | "
      f"{run['mapping_ms_median']:.0f} / {run['mapping_ms_p95']:.0f} |")
EOF2
}

echo "| run | frames | KFs / 100 frames | tracked | ATE | ATE / path | tracking median / p95 [ms] | mapping median / p95 [ms/KF] |"
echo "|---|---|---|---|---|---|---|---|"
[[ -z "${SKIP_HALL3:-}" ]] && for a in ${HALL3_AGENTS:-0 1 2}; do run "hall3-agent$a" --sim "${SIM:-hall3}" --sim-agent "$a"; done
if [[ -z "${SKIP_REAL:-}" && -d "$DATA/kitti07_first160" ]]; then
  export GT_KITTI="$DATA/kitti07_first160/poses_07_first160_kitti.txt" KITTI_TIMES="$DATA/kitti07_first160/times_first160.txt"
  run kitti07-160 --dataset "$DATA/kitti07_first160" --format kitti
  [[ -z "${SKIP_ROAD:-}" ]] && run kitti07-160-road --dataset "$DATA/kitti07_first160" --format kitti --config "$ROOT/deploy/config/agent-road.yaml"
fi
if [[ -z "${SKIP_REAL:-}" && -d "$DATA/ntsd150_euroc" ]]; then
  unset GT_KITTI KITTI_TIMES
  run ntsd-150 --dataset "$DATA/ntsd150_euroc" --format euroc
fi
