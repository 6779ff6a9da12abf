#!/usr/bin/env python3
"""Agents on real / photorealistic sequences (issue 27 item 5) through ccm_replay.

Each case takes two or three overlapping frame ranges of one excerpt in ../shared/data as
agents (ccm_replay --dataset DIR@FIRST-LAST), runs the agents' VO and the server back-end, and
checks against the dataset's ground truth what holds today, with bounds measured first and
then loosened (docs/server.md, "Two agents on real sequences", has the measured numbers):
every agent tracks, their VO ATE, the outputs of every map, and where the maps fuse today:
one map, each fusion found in a stretch two agents drove, its joint ATE and the scale ratio
between the agents' parts. Prints the numbers it measured.
Exit 77 (skipped, with a message) when the excerpt is absent.
"""
import argparse
import json
import os
import subprocess
import sys
import time

# ranges: the agents' frames; shared: the frames two of them drove (one stretch per pair of
# neighbours, in order); bounds (measured today):
# tracked share, VO ATE in % of each agent's path (its own keyframe trajectory in this run,
# own Sim(3) alignment; its VO tracks the map the server shares), and for cases that fuse
# today the joint ATE in % of the fused map's path and the scale ratio between the parts.
CASES = {
    # Two cars on the same road, 40 frames (~23 m) apart in time; real driving (KITTI 07).
    # Measured: tracked 94 / 97 %, VO 0.58 / 0.32 %, 1 map, fused on agent 2's 9th
    # frame, joint ATE 0.33 m = 0.28 % (2026-11-27: 0.36-0.38 m), scale ratio 1.018 (was
    # 1.024-1.026); the bound is the 2 % goal with room for run-to-run spread.
    "kitti07": dict(folder="kitti07_first160", ranges=("0-99", "60-159"), ground_truth="poses_07_first160_kitti.txt",
                    road=True, shared=[(60, 99)], min_tracked=0.85, max_vo_ate_pct=1.0, fuses=True,
                    max_joint_ate_pct=0.75, max_scale_ratio=1.05),
    # New Tsukuba (photorealistic CG), one hand-held sweep split with 30 shared frames.
    # Measured: tracked 87 / 96 %, VO 0.10 / 0.27 %, 1 map, joint ATE 0.0052 m = 0.13 %
    # (2026-11-27: 0.0077 m), scale ratio 1.008 (was 1.018).
    "ntsd150": dict(folder="ntsd150_euroc", ranges=("0-89", "60-149"), shared=[(60, 89)], min_tracked=0.75,
                    max_vo_ate_pct=1.0, fuses=True, max_joint_ate_pct=0.5, max_scale_ratio=1.05),
    # The same sweep with 10 shared frames: the second agent starts as the first one ends.
    # Today the maps do not fuse (fusion candidates stop at BoW matches and RANSAC). The
    # second agent's VO used to initialize while the camera turns and drift 3.5 % of its
    # path; the start check (a rival motion explained that view as well, docs/vo.md "A rival
    # motion") now refuses it and starts ~25 frames later: tracked 53/80, VO 0.05 %. Fusion
    # is not asserted either way; if the maps fuse, the fused map must be sound.
    "ntsd150-short": dict(folder="ntsd150_euroc", ranges=("0-79", "70-149"), shared=[(70, 79)], min_tracked=0.6,
                          max_vo_ate_pct=1.0, fuses=False, max_joint_ate_pct=2.0, max_scale_ratio=1.2),
    # Three cars in a chain (1-2 share frames 45-69, 2-3 frames 90-114), a split nobody tuned
    # on. Measured 2026-12-06: tracked 91 / 84 / 99 %, VO 1.05 / 0.05 / 0.41 % (the first car's
    # 70 frames drift more than the first 100 do: 0.31 m either way), 1 map after 2 fusions
    # (on frames 94 and 55), joint ATE 0.297 m = 0.25 % of 119.5 m, scale ratio 1.037
    # (parts at own-alignment ATE 0.43 / 0.14 / 0.23 m). The scale bound is wider than the
    # two-car case's because the parts lie further apart along the road: one agent driving all
    # 160 frames (server map) has its first and last thirds 1.040 apart in scale (monocular drift).
    "kitti07-three": dict(folder="kitti07_first160", ranges=("0-69", "45-114", "90-159"),
                          ground_truth="poses_07_first160_kitti.txt", road=True, shared=[(45, 69), (90, 114)],
                          min_tracked=0.75, max_vo_ate_pct=1.5, fuses=True, max_joint_ate_pct=0.75,
                          max_scale_ratio=1.07),
    # The New Tsukuba sweep as three agents in a chain (shared 40-64 and 80-104), not tuned
    # on. Measured 2026-12-06: tracked 82 / 95 / 91 %, VO 0.07 / 0.31 / 0.08 %, 1 map after 2
    # fusions (on frames 33 and 80), joint ATE 0.0046 m = 0.094 % of 4.9 m, scale ratio 1.012.
    "ntsd150-three": dict(folder="ntsd150_euroc", ranges=("0-64", "40-104", "80-149"), shared=[(40, 64), (80, 104)],
                          min_tracked=0.6, max_vo_ate_pct=1.0, fuses=True, max_joint_ate_pct=0.5,
                          max_scale_ratio=1.05),
}

# Frames before or after the shared stretch whose view can still overlap it (see check_bounds).
FUSION_FRAME_MARGIN = 15


def fail(message):
    print("FAIL: " + message)
    sys.exit(1)


def rows(path):
    with open(path) as f:
        return [l.split() for l in f if l.strip() and not l.startswith("#")]


def check_maps(case, out, summary):
    """Every map's trajectories are written and hold what summary.json says."""
    in_maps = set()
    for m in summary["maps"]:
        for p in m["parts"]:
            if p["keyframes"] == 0:
                continue
            n = len(rows(os.path.join(out, p["trajectory"])))
            if n != p["keyframes"]:
                fail(f"{p['trajectory']}: {n} keyframes, summary.json says {p['keyframes']}")
            in_maps.add(p["name"])
    names = {a["name"] for a in summary["agents"]}
    if in_maps != names:
        fail(f"agents in no written map: {sorted(names - in_maps)}")


def fusion_frame(case, out, summary, fusion):
    """Frame index (of the sequence) of the keyframe whose match fused the maps."""
    agent = next(a for a in summary["agents"] if a["id"] == fusion["agent"])
    stamps = [round(float(r[0]) * 1e9) for r in rows(os.path.join(out, agent["name"] + "_ground_truth.tum"))]
    first = int(case["ranges"][fusion["agent"] - 1].split("-")[0])
    nearest = min(range(len(stamps)), key=lambda i: abs(stamps[i] - fusion["stamp_ns"]))
    return first + nearest


def report(case, out, summary, wall_s):
    print(f"wall {wall_s:.1f} s (replay's own clock {summary['wall_s']:.1f} s)")
    for a in summary["agents"]:
        ate = a["standalone_ate_m"]["rmse"]
        print(f"  {a['name']}: tracked {a['frames_tracked']}/{a['frames']}, {a['segments']} segment(s), "
              f"{a['keyframes_created']} keyframes, path {a['path_m']:.2f} m, VO ATE {ate:.4f} m "
              f"({100 * ate / a['path_m']:.3f} %)")
    for m in summary["maps"]:
        acc = m["accuracy"] or {}
        parts = "; ".join(f"{p['name']} {p['keyframes']} KFs, scale {p.get('scale_to_ground_truth', 0):.4f}, "
                          f"ATE {p.get('ate_m', {}).get('rmse', 0):.4f} m, alone {p.get('own_ate_m', {}).get('rmse', 0):.4f} m"
                          for p in m["parts"])
        print(f"  map {m['id']}: joint ATE {acc.get('joint_ate_m', {}).get('rmse', 0):.4f} m = "
              f"{acc.get('joint_ate_percent_of_path', 0):.3f} % of {acc.get('path_m', 0):.1f} m, "
              f"scale ratio {acc.get('scale_ratio', 0):.4f} ({parts})")
    for e in summary["events"]:
        if e["kind"] == "fusion":
            print(f"  fusion at {e['time_s']:.1f} s wall on agent {e['agent']}'s keyframe of frame "
                  f"{fusion_frame(case, out, summary, e)}: {e['detail']}")
    print("  place recognition:", json.dumps(summary["place_recognition"]))


def check_bounds(case, out, summary):
    for a in summary["agents"]:
        if a["frames_tracked"] < case["min_tracked"] * a["frames"]:
            fail(f"{a['name']} tracked {a['frames_tracked']} of {a['frames']} frames")
        ate_pct = 100 * a["standalone_ate_m"]["rmse"] / a["path_m"]
        if not a["standalone_ate_m"]["count"] or ate_pct > case["max_vo_ate_pct"]:
            fail(f"{a['name']}: VO ATE {ate_pct:.3f} % of its path (bound {case['max_vo_ate_pct']} %)")
    maps = summary["maps"]
    agents = len(case["ranges"])
    if case["fuses"] and (len(maps) != 1 or summary["fusions"] < agents - 1):
        fail(f"the agents' maps fused into one until now; now {len(maps)} maps, {summary['fusions']} fusions")
    if len(maps) > agents:
        fail(f"{len(maps)} maps from {agents} agents (each kept one VO segment until now: at most {agents} maps)")
    if len(maps) == 1:
        acc = maps[0]["accuracy"]
        if acc["joint_ate_percent_of_path"] > case["max_joint_ate_pct"]:
            fail(f"fused map: joint ATE {acc['joint_ate_percent_of_path']:.3f} % (bound {case['max_joint_ate_pct']} %)")
        if not 0 < acc["scale_ratio"] <= case["max_scale_ratio"]:
            fail(f"fused map: the agents' parts differ in scale by {acc['scale_ratio']:.4f} "
                 f"(bound {case['max_scale_ratio']})")
        # A keyframe a few frames before the shared stretch already sees what the other agent
        # sees at its start (the camera looks ahead), so the fusion may come from there; the
        # joint ATE and scale ratio above judge whether it was right.
        def near_shared(frame):
            return any(lo - FUSION_FRAME_MARGIN <= frame <= hi + FUSION_FRAME_MARGIN for lo, hi in case["shared"])
        for e in summary["events"]:
            frame = fusion_frame(case, out, summary, e) if e["kind"] == "fusion" else None
            if frame is not None and not near_shared(frame):
                fail(f"fused on frame {frame}, not within {FUSION_FRAME_MARGIN} frames of frames two "
                     f"agents saw {case['shared']}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=sorted(CASES), required=True)
    ap.add_argument("--replay", required=True, help="ccm_replay binary")
    ap.add_argument("--vocab", required=True)
    ap.add_argument("--data", required=True, help="the shared data folder (../shared/data beside the repository)")
    ap.add_argument("--road-config", required=True, help="deploy/config/agent-road.yaml (KITTI's VO profile)")
    ap.add_argument("--work", required=True)
    args = ap.parse_args()
    case = CASES[args.case]
    folder = os.path.join(args.data, case["folder"])
    if not os.path.isdir(folder):
        print(f"SKIPPED: {folder} is absent (real excerpts live in ../shared/data beside the repository, "
              f"see its README.md); real-data case {args.case} not run")
        sys.exit(77)
    out = os.path.join(args.work, "out")
    os.makedirs(args.work, exist_ok=True)
    cmd = [args.replay, "--vocab", args.vocab, "--out", out]
    for r in case["ranges"]:
        cmd += ["--dataset", f"{folder}@{r}"]
    if "ground_truth" in case:
        cmd += ["--ground-truth", os.path.join(folder, case["ground_truth"])]
    if case.get("road"):
        cmd += ["--agent-config", args.road_config]
    print(" ".join(cmd))
    start = time.monotonic()
    with open(os.path.join(args.work, "replay.log"), "w") as log:
        code = subprocess.call(cmd, stdout=log, stderr=subprocess.STDOUT)
    wall_s = time.monotonic() - start
    if code != 0:
        print(open(os.path.join(args.work, "replay.log")).read()[-3000:])
        fail(f"ccm_replay exited with {code}")
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    report(case, out, summary, wall_s)
    check_maps(case, out, summary)
    check_bounds(case, out, summary)
    print("OK")


if __name__ == "__main__":
    main()
