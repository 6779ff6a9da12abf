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
echo "OK"
