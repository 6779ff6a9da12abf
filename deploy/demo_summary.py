#!/usr/bin/env python3
"""Composes demo-out/summary.json from what the demo's processes wrote, and prints it as a
table: per-agent and collaborative ATE (ccm_eval on the server's keyframe trajectories in
the fused map's frame against the simulator's ground truth), fusion and loop events with
their times, traffic per agent in both directions, keyframes sent/acknowledged/lost.

usage: demo_summary.py OUT_DIR NUM_AGENTS
"""
import json
import sys


def last_json_line(path):
    with open(path) as f:
        lines = [l for l in f if l.startswith("{")]
    return json.loads(lines[-1]) if lines else None


def flight_seconds(tum):
    try:
        with open(tum) as f:
            stamps = [float(l.split()[0]) for l in f if l.strip() and not l.startswith("#")]
    except OSError:
        return 0.0
    return stamps[-1] - stamps[0] if len(stamps) > 1 else 0.0


def main():
    out, n = sys.argv[1], int(sys.argv[2])
    server = json.load(open(f"{out}/server/server.json"))
    backend = json.load(open(f"{out}/server/summary.json"))
    evaluation = json.load(open(f"{out}/eval.json"))
    ate = {a["name"]: a for a in evaluation["agents"]}
    agents = []
    for i in range(1, n + 1):
        a = last_json_line(f"{out}/agent{i}.log") or {}
        link = a.get("link", {})
        traffic = a.get("traffic", {})
        up = sum(v for k, v in traffic.items() if k.endswith(":out"))
        down = sum(v for k, v in traffic.items() if k.endswith(":in"))
        # Per second of flight (data time; the demo plays at DEMO_RATE x real time).
        wall = flight_seconds(f"{out}/agent{i}_ground_truth.tum") or a.get("wall_s", 0.0) or 1.0
        e = ate.get(f"agent{i}", {})
        agents.append({
            "agent": i,
            "frames": a.get("frames"),
            "tracked": a.get("tracked"),
            "keyframes_created": a.get("keyframes_created"),
            "keyframes_sent": link.get("kfs_sent"),
            "keyframes_sent_as_anchors": link.get("kfs_sent_as_anchors"),
            "keyframes_resent": link.get("kfs_resent"),
            "keyframes_acked": link.get("kfs_acked"),
            "keyframes_unacked": link.get("kfs_unacked"),
            "keyframes_lost": a.get("keyframes_lost"),
            "server_keyframes_received": link.get("server_keyframes_received"),
            "uplink_bytes": up,
            "downlink_bytes": down,
            "uplink_mb_per_s": up / wall / 1e6,
            "downlink_mb_per_s": down / wall / 1e6,
            "collaborative_ate_m": (e.get("ate_joint_m") or {}).get("rmse"),
            "trajectory": f"agent{i}_keyframes.tum",
        })
    events = [{"kind": e["kind"], "time_s": round(e["time_s"], 1), "agent": e["agent"], "detail": e["detail"]}
              for e in backend["events"] if e["kind"] in ("fusion", "loop", "new_map")]
    joint = evaluation.get("joint", {}).get("ate_m", {})
    summary = {
        "collaborative_ate_m": joint.get("rmse"),
        "maps_at_end": len(backend["maps"]),
        "fusions": backend["fusions"],
        "loops": backend["loops"],
        "agents": agents,
        "events": events,
        "server": {"rejected": server["rejected"], "refused_agents": server["refused_agents"]},
        "files": ["map.ply", "map_top.png"] + [a["trajectory"] for a in agents],
    }
    with open(f"{out}/summary.json", "w") as f:
        json.dump(summary, f, indent=2)

    print(f"[demo] maps at the end: {summary['maps_at_end']}, fusions: {summary['fusions']}, "
          f"loops: {summary['loops']}, collaborative ATE: {summary['collaborative_ate_m']:.4f} m")
    for e in events:
        print(f"[demo]   {e['time_s']:7.1f} s  {e['kind']:8s} agent {e['agent']}: {e['detail']}")
    print("[demo] agent  frames  KFs sent/acked/lost  up MB/s  down MB/s (per s of flight)  ATE [m]")
    for a in agents:
        ate_m = a["collaborative_ate_m"]
        print(f"[demo] {a['agent']:5d}  {a['frames']:6d}  {a['keyframes_sent']:4d}/{a['keyframes_acked']:4d}/"
              f"{a['keyframes_lost']:<4d}       {a['uplink_mb_per_s']:7.3f}  {a['downlink_mb_per_s']:9.3f}  "
              f"{ate_m if ate_m is None else round(ate_m, 4)}")


if __name__ == "__main__":
    main()
