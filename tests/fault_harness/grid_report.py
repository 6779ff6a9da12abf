#!/usr/bin/env python3
"""Table and plot of a fault-grid run (run_grid.sh): OUT/grid.md, OUT/grid.json, OUT/grid.png.
Traffic is in MB per second of flight (the simulator's data time), whatever the playback rate.

usage: grid_report.py OUT "1 2 3" "perfect delay loss20 loss50"
"""
import json
import math
import os
import sys

LABELS = {"perfect": "perfect", "delay": "delay 0.5 s", "loss20": "P_loss 0.2", "loss50": "P_loss 0.5"}


def last_json_line(path):
    try:
        with open(path) as f:
            lines = [l for l in f if l.startswith("{")]
        return json.loads(lines[-1]) if lines else None
    except OSError:
        return None


def flight_seconds(tum):
    stamps = []
    with open(tum) as f:
        for line in f:
            v = line.split()
            if v and not line.startswith("#"):
                stamps.append(float(v[0]))
    return stamps[-1] - stamps[0] if len(stamps) > 1 else 0.0


def path_length(tum):
    pts = []
    with open(tum) as f:
        for line in f:
            v = line.split()
            if len(v) >= 4 and not line.startswith("#"):
                pts.append(tuple(map(float, v[1:4])))
    return sum(math.dist(a, b) for a, b in zip(pts, pts[1:]))


def cell(out, n, cond):
    d = f"{out}/{n}agents_{cond}"
    row = {"agents": n, "condition": cond, "complete": True}
    ups, downs, lost, unacked, resent, created, acked = [], [], 0, 0, 0, 0, 0
    path = 0.0
    for a in range(1, n + 1):
        j = last_json_line(f"{d}/agent{a}.log")
        if not j:
            row["complete"] = False
            continue
        # Per second of flight (data time): the grid may play the flights slower than real
        # time (GRID_RATE) so that the agents' VO keeps up on a small machine.
        gt = f"{d}/gt{a}.tum"
        wall = (flight_seconds(gt) if os.path.exists(gt) else 0.0) or j.get("wall_s") or 1.0
        t = j.get("traffic", {})
        ups.append(sum(v for k, v in t.items() if k.endswith(":out")) / wall / 1e6)
        downs.append(sum(v for k, v in t.items() if k.endswith(":in")) / wall / 1e6)
        link = j.get("link", {})
        lost += j.get("keyframes_lost", 0)
        unacked += link.get("kfs_unacked", 0)
        resent += link.get("kfs_resent", 0)
        created += j.get("keyframes_created", 0)
        acked += link.get("kfs_acked", 0)
        if os.path.exists(f"{d}/gt{a}.tum"):
            path += path_length(f"{d}/gt{a}.tum")
    row.update(uplink_mb_s=sum(ups) / len(ups) if ups else None, downlink_mb_s=sum(downs) / len(downs) if downs else None,
               keyframes_created=created, keyframes_acked=acked, keyframes_lost=lost, keyframes_unacked=unacked,
               keyframes_resent=resent, path_m=path)
    s = last_json_line(f"{d}/server.log") or {}
    row["fusions"] = s.get("fusions")
    try:
        e = json.load(open(f"{d}/eval.json"))
        row["ate_m"] = e["joint"]["ate_m"]["rmse"]
    except (OSError, KeyError, ValueError):
        row["ate_m"] = None
    row["ate_percent"] = 100 * row["ate_m"] / path if row["ate_m"] is not None and path > 0 else None
    return row


def fmt(v, digits=3):
    return "-" if v is None else f"{v:.{digits}f}"


def main():
    out, agents, conds = sys.argv[1], [int(a) for a in sys.argv[2].split()], sys.argv[3].split()
    rows = [cell(out, n, c) for n in agents for c in conds]
    json.dump(rows, open(f"{out}/grid.json", "w"), indent=2)
    lines = ["| agents | link | up MB/s per agent | down MB/s per agent | KFs created | acked | lost | unacked at end "
             "| resent | fusions | ATE [m] | ATE [% path] |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['agents']} | {LABELS.get(r['condition'], r['condition'])} | {fmt(r['uplink_mb_s'])} | "
                     f"{fmt(r['downlink_mb_s'])} | {r['keyframes_created']} | {r['keyframes_acked']} | "
                     f"{r['keyframes_lost']} | {r['keyframes_unacked']} | {r['keyframes_resent']} | {r['fusions']} | "
                     f"{fmt(r['ate_m'], 4)} | {fmt(r['ate_percent'], 3)} |")
    open(f"{out}/grid.md", "w").write("\n".join(lines) + "\n")
    print("\n".join(lines))
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("(no matplotlib: grid.png not written)")
        return
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    width = 0.8 / len(conds)
    for i, c in enumerate(conds):
        xs = [n + (i - (len(conds) - 1) / 2) * width for n in agents]
        sel = [r for r in rows if r["condition"] == c]
        label = LABELS.get(c, c)
        axes[0].bar(xs, [r["uplink_mb_s"] or 0 for r in sel], width, label=label)
        axes[1].bar(xs, [r["keyframes_lost"] + r["keyframes_unacked"] for r in sel], width, label=label)
        axes[2].bar(xs, [(r["ate_m"] or 0) * 100 for r in sel], width, label=label)
    for ax, title in zip(axes, ["agent -> server [MB/s per agent]", "keyframes lost + unacknowledged",
                                "collaborative ATE [cm]"]):
        ax.set_title(title)
        ax.set_xticks(agents)
        ax.set_xlabel("agents")
    axes[0].axhline(0.1, color="k", ls="--", lw=1)
    # A count axis from 0 up (an all-zero row would otherwise be drawn around -0.04..0.04).
    axes[1].set_ylim(0, max(1, max(r["keyframes_lost"] + r["keyframes_unacked"] for r in rows) * 1.1))
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(f"{out}/grid.png", dpi=100)
    print(f"wrote {out}/grid.md, grid.json, grid.png")


if __name__ == "__main__":
    main()
