#!/usr/bin/env bash
# ccm_replay on two agents given as EuRoC dataset folders (rendered by ccm_sim from hall3):
# their maps must fuse, and the outputs must be there. Bad input must fail with a message.
# Then: a run that ends with two maps writes both; a frame range of a folder is one agent.
# Usage: replay_datasets_test.sh CCM_SIM CCM_REPLAY VOCABULARY WORK_DIR
set -euo pipefail
sim="$1" replay="$2" vocab="$3" work="$4"
rm -rf "$work" && mkdir -p "$work"
"$sim" --scenario hall3 --agents 0,1 --seconds 24 --out "$work/data" > "$work/sim.log"
"$replay" --dataset "$work/data/agent0" --dataset "$work/data/agent1" --vocab "$vocab" --out "$work/out" \
  > "$work/replay.log" 2>&1 || { cat "$work/replay.log"; exit 1; }
tail -n 12 "$work/replay.log"
for f in summary.json map.ply map_top.png agent0_keyframes.tum agent1_keyframes.tum agent0_ground_truth.tum; do
  [ -s "$work/out/$f" ] || { echo "missing output $f"; exit 1; }
done
grep -q '"fusions": [1-9]' "$work/out/summary.json" || { echo "the two overlapping flights did not fuse"; exit 1; }
maps=$(grep -c '"anchored_keyframes"' "$work/out/summary.json")
[ "$maps" -eq 1 ] || { echo "expected one map at the end, got $maps"; exit 1; }
# Bad input: a folder that is not a dataset, a missing vocabulary.
if "$replay" --dataset "$work/nope" --vocab "$vocab" --out "$work/bad" > "$work/bad.log" 2>&1; then
  echo "a missing dataset folder was accepted"; exit 1
fi
grep -q "error" "$work/bad.log" || { echo "no error message for a missing dataset"; exit 1; }
if "$replay" --dataset "$work/data/agent0" --vocab "$work/nope.ccmvoc" --out "$work/bad" > "$work/bad2.log" 2>&1; then
  echo "a missing vocabulary was accepted"; exit 1
fi
grep -q "nope.ccmvoc" "$work/bad2.log" || { echo "the error does not name the missing vocabulary"; cat "$work/bad2.log"; exit 1; }
# --agent-config: the agents run with a deployed agent's YAML (here a sparse keyframe rule:
# several times fewer keyframes than the default run above), and a bad file is refused.
printf 'vo:\n  kf_tracked_ratio: 0.6\n  kf_urgent_ratio: 0.4\n' > "$work/sparse.yaml"
"$replay" --dataset "$work/data/agent0" --vocab "$vocab" --agent-config "$work/sparse.yaml" --no-final-ba \
  --out "$work/sparse" > "$work/sparse.log" 2>&1 || { cat "$work/sparse.log"; exit 1; }
kfs() { python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["agents"][0]["keyframes_created"])' "$1"; }
default_kfs=$(kfs "$work/out/summary.json") sparse_kfs=$(kfs "$work/sparse/summary.json")
echo "agent0 keyframes: default $default_kfs, kf_tracked_ratio 0.6: $sparse_kfs"
[ $((2 * sparse_kfs)) -lt "$default_kfs" ] || { echo "--agent-config did not reach the VO"; exit 1; }
printf 'vo:\n  kf_tracked_ratio: 2\n' > "$work/bad.yaml"
if "$replay" --dataset "$work/data/agent0" --vocab "$vocab" --agent-config "$work/bad.yaml" --out "$work/bad" \
  > "$work/bad3.log" 2>&1; then
  echo "an invalid agent config was accepted"; exit 1
fi
grep -q "kf_tracked_ratio" "$work/bad3.log" || { echo "the error does not name the bad key"; cat "$work/bad3.log"; exit 1; }
# Every map is written, not only the largest: disjoint2's two rooms (100 m apart) never fuse.
"$replay" --sim disjoint2 --max-frames 60 --vocab "$vocab" --out "$work/d2" > "$work/d2.log" 2>&1 \
  || { cat "$work/d2.log"; exit 1; }
python3 - "$work/d2" <<'EOF2' || { cat "$work/d2.log"; exit 1; }
import json, os, sys
d = sys.argv[1]
maps = json.load(open(f"{d}/summary.json"))["maps"]
assert len(maps) == 2, f"disjoint2: expected 2 maps, summary.json lists {len(maps)}"
assert sorted(a for m in maps for a in m["agents"]) == [1, 2], "each agent in its own map"
for m in maps:
    for p in m["parts"]:
        rows = [l for l in open(os.path.join(d, p["trajectory"])) if l.strip() and not l.startswith("#")]
        assert p["trajectory"].startswith(f"map{m['id']}_") and len(rows) == p["keyframes"] > 0, p
    assert m["accuracy"]["joint_ate_m"]["rmse"] < 0.05, f"map {m['id']} is off its room's ground truth"
EOF2
grep -q "map .*agents agent0" "$work/d2.log" && grep -q "map .*agents agent1" "$work/d2.log" \
  || { echo "the console summary does not list both maps with their agents"; cat "$work/d2.log"; exit 1; }
# DIR@FIRST-LAST: one agent from a slice of a folder (frames 100-159), named after it.
"$replay" --dataset "$work/data/agent0@100-159" --vocab "$vocab" --no-final-ba --out "$work/range" \
  > "$work/range.log" 2>&1 || { cat "$work/range.log"; exit 1; }
first_stamp=$(awk -F, 'NR == 102 {print $1}' "$work/data/agent0/mav0/cam0/data.csv")
python3 - "$work/range" "$first_stamp" <<'EOF2' || exit 1
import json, sys
d, first_stamp = sys.argv[1], int(sys.argv[2])
a = json.load(open(f"{d}/summary.json"))["agents"][0]
assert a["name"] == "agent0_100-159" and a["frames"] == 60, a
gt = [l.split()[0] for l in open(f"{d}/agent0_100-159_ground_truth.tum") if l.strip() and not l.startswith("#")]
assert len(gt) == 60 and abs(float(gt[0]) * 1e9 - first_stamp) < 1e3, (len(gt), gt[0], first_stamp)
EOF2
for bad in "agent0@100-99999" "agent0@9-3" "agent0@60"; do
  if "$replay" --dataset "$work/data/$bad" --vocab "$vocab" --out "$work/bad" > "$work/bad4.log" 2>&1; then
    echo "a bad frame range ($bad) was accepted"; exit 1
  fi
  grep -q "frame range" "$work/bad4.log" || { echo "no frame-range message for $bad"; cat "$work/bad4.log"; exit 1; }
done
echo "OK"
