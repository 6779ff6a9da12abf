#!/usr/bin/env python3
"""Totals of a bench_fusion run from its results.jsonl (one line per finished scene).

bench_fusion prints these totals itself at the end (fusion_report.cc, Report); this script
gives the same totals for a run that was stopped early or for a chosen subset of scenes, and
splits them by layout and texture profile. Definitions as in fusion_report.cc:
  bench_fusion --set held-out --jobs 2 --out out   # (interrupted)
  tests/bench/fusion_totals.py out/results.jsonl [--seeds 1001-1030]
"""
import argparse
import json
import statistics
import sys
from collections import defaultdict


def parse_seeds(text):
    seeds = set()
    for item in text.split(","):
        lo, _, hi = item.partition("-")
        seeds.update(range(int(lo), int(hi or lo) + 1))
    return seeds


def pct(n, d):
    return f"{n}/{d} = {100.0 * n / d:.0f} %" if d else "-"


def totals(scenes):
    t = defaultdict(int)
    to_fusion, pr_ms, ratios, spreads = [], [], [], []
    by_kind = defaultdict(lambda: [0, 0])
    for s in scenes:
        for p in s.get("pairs", []):
            if not p["qualifies"]:
                continue
            t["q"] += 1
            by_kind[p["kind"]][1] += 1
            if p["fused"]:
                t["qf"] += 1
                by_kind[p["kind"]][0] += 1
                if p["seconds_to_fusion"] >= 0:
                    to_fusion.append(p["seconds_to_fusion"])
        t["ff"] += sum(f["wrong"] for f in s.get("fusions", []))
        t["fl"] += sum(l["wrong"] for l in s.get("loops", []))
        for a in s.get("agent_vo", []):
            t["agents"] += 1
            t["rev"] += a["revisits"]
            t["rev_loop"] += a["revisits"] and a["loops"] > 0
            # Older results.jsonl files have no revisit links: counted as not joined.
            t["rev_joined"] += a["revisits"] and a.get("revisit_joined", False)
            t["false_links"] += a.get("false_revisit_links", 0)
            # Older files have no keyframe count from the revisit on: held by a loop or a link only.
            t["rev_held"] += a.get("revisit_held", a["revisits"] and (a["loops"] > 0 or a.get("revisit_joined", False)))
            t["good_vo"] += 0 <= a["ate_path_pct"] <= 1.0 and a["tracked"] > 0.9
            t["tracked_full"] += a["tracked"] >= 0.99
        fused = [m for m in s.get("maps", []) if len(m["agents"]) > 1 and m["joint_ate_m"] >= 0 and m["mean_standalone_ate_m"] > 0]
        if fused:
            worst = max(m["joint_ate_m"] / m["mean_standalone_ate_m"] for m in fused)
            spread = max(m["scale_spread"] for m in fused)
            t["fused_scenes"] += 1
            t["good_ate"] += worst <= 1.0
            t["good_scale"] += spread <= 0.02
            ratios.append(worst)
            spreads.append(spread)
        pr_ms.append(s["place_recognition_ms"])
        ba = s.get("global_ba", {})
        t["ba_runs"] += ba.get("runs", 0)
        t["ba_s"] += ba.get("total_s", 0.0)
        if ba.get("max_s", 0.0) > t["ba_max_s"]:
            t["ba_max_s"], t["ba_max_kfs"] = ba["max_s"], ba.get("max_keyframes", 0)
    return t, to_fusion, pr_ms, ratios, spreads, by_kind


def print_totals(title, scenes):
    t, to_fusion, pr_ms, ratios, spreads, by_kind = totals(scenes)
    med = lambda v: f"{statistics.median(v):.2f}" if v else "-"
    print(f"{title}: {len(scenes)} scenes, {t['agents']} agents")
    print(f"  qualifying pairs fused: {pct(t['qf'], t['q'])} [>= 90 %]")
    for kind, (f, n) in sorted(by_kind.items()):
        print(f"    {kind}: {pct(f, n)}")
    print(f"  false fusions: {t['ff']} [0]; false loops: {t['fl']}")
    print(f"  median seconds of flight from the first overlap to the fusion: {med(to_fusion)} [<= 5]")
    print(f"  revisiting agents with at least one loop: {pct(t['rev_loop'], t['rev'])} [all]")
    print(f"  revisiting agents whose revisit the map holds once (a true revisit link): "
          f"{pct(t['rev_joined'], t['rev'])}; false revisit links: {t['false_links']}")
    print(f"  revisiting agents whose revisit the map holds (a loop, a true revisit link, or every revisit flown in the map it had:\n"
          f"    no keyframe of its own from the first revisit on, tracking >= 99 %): {pct(t['rev_held'], t['rev'])}")
    print(f"  scenes whose fused maps are at least as accurate as their agents' VO: "
          f"{pct(t['good_ate'], t['fused_scenes'])} [>= 90 %] (worst joint / VO ATE per scene: median {med(ratios)})")
    print(f"  scenes whose fused maps agree in scale within 2 %: {pct(t['good_scale'], t['fused_scenes'])}"
          f" (worst spread per scene: median {100 * statistics.median(spreads) if spreads else 0:.1f} %)")
    print(f"  agents whose VO is within 1 % of its path (and tracks > 90 %): {pct(t['good_vo'], t['agents'])} [>= 95 %]")
    print(f"  agents tracking >= 99 % of their frames: {pct(t['tracked_full'], t['agents'])}")
    print(f"  place recognition per keyframe (mean per scene, median over scenes): {med(pr_ms)} ms [<= 5]")
    if t["ba_runs"]:
        print(f"  global BAs: {t['ba_runs']}, {t['ba_s']:.1f} s in total, the longest {t['ba_max_s']:.2f} s "
              f"({t['ba_max_kfs']} keyframes)")


def compare(scenes, others):
    """Per seed: the worst fused map's joint / VO ATE ratio and the global BA seconds of both runs."""
    other = {s["seed"]: s for s in others}
    print("| seed | worst joint/VO (this) | (other) | global BA s (this) | (other) | pairs fused (this) | (other) |")
    print("|---|---|---|---|---|---|---|")
    for s in scenes:
        o = other.get(s["seed"])
        if not o:
            continue
        def cells(x):
            fused = [m for m in x.get("maps", []) if len(m["agents"]) > 1 and m["joint_ate_m"] >= 0
                     and m["mean_standalone_ate_m"] > 0]
            worst = max((m["joint_ate_m"] / m["mean_standalone_ate_m"] for m in fused), default=-1)
            q = [p for p in x.get("pairs", []) if p["qualifies"]]
            return (f"{worst:.2f}" if worst >= 0 else "-", f"{x.get('global_ba', {}).get('total_s', 0):.1f}",
                    f"{sum(p['fused'] for p in q)}/{len(q)}")
        a, b = cells(s), cells(o)
        print(f"| {s['seed']} | {a[0]} | {b[0]} | {a[1]} | {b[1]} | {a[2]} | {b[2]} |")

def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", help="results.jsonl of a bench_fusion run")
    ap.add_argument("--seeds", help="only these seeds, e.g. 1001-1030")
    ap.add_argument("--by", choices=["layout", "textures", "agents"], help="also split the totals by this")
    ap.add_argument("--against", help="another results.jsonl: per-seed table of both runs")
    args = ap.parse_args()
    try:
        with open(args.results) as f:
            scenes = [json.loads(l) for l in f if l.strip()]
    except (OSError, ValueError) as e:
        print(f"error: {args.results}: {e}", file=sys.stderr)
        return 2
    failed = [s["seed"] for s in scenes if s.get("error")]
    scenes = [s for s in scenes if not s.get("error")]
    if args.seeds:
        wanted = parse_seeds(args.seeds)
        scenes = [s for s in scenes if s["seed"] in wanted]
    if failed:
        print(f"scenes that failed to run (left out): {failed}")
    scenes.sort(key=lambda s: s["seed"])
    print_totals("all", scenes)
    if args.against:
        with open(args.against) as f:
            compare(scenes, [json.loads(l) for l in f if l.strip()])
    if args.by:
        groups = defaultdict(list)
        for s in scenes:
            groups[s[args.by]].append(s)
        for key, group in sorted(groups.items()):
            print_totals(f"{args.by} {key}", group)
    return 0


if __name__ == "__main__":
    sys.exit(main())
