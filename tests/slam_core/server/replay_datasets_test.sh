#!/usr/bin/env bash
# ccm_replay on two agents given as EuRoC dataset folders (rendered by ccm_sim from hall3):
# their maps must fuse, and the outputs must be there. Bad input must fail with a message.
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
echo "OK"
