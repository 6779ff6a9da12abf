#!/usr/bin/env python3
"""long_flight.sh's verdict: the agent's summary counters and OUT/samples.csv at each tenth of
the flight, written to OUT/long_flight.md; exit 0 when nothing was lost and memory, CPU per
frame and the unacknowledged keyframes stayed flat after the warm-up (criteria: long_flight.sh).

usage: long_flight_report.py OUT AGENT_RC WITH_SERVER WARMUP_MIN RSS_SLACK_MB CPU_RATIO
"""
import csv
import pathlib
import statistics
import sys

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from grid_report import last_json_line as last_json  # noqa: E402  (the fault grid's summary reader)


def num(row, key):
    return float(row[key]) if row.get(key) not in (None, "") else None


def tenth_median(rows, key, last):
    """Median of key over the first (or last) tenth of rows, at least 3 rows."""
    n = max(3, len(rows) // 10)
    part = rows[-n:] if last else rows[:n]
    values = [num(r, key) for r in part if num(r, key) is not None]
    return statistics.median(values) if values else None


def main():
    out, agent_rc = pathlib.Path(sys.argv[1]), int(sys.argv[2])
    with_server, warmup = sys.argv[3] == "1", float(sys.argv[4])
    slack, cpu_ratio = float(sys.argv[5]), float(sys.argv[6])
    rows = list(csv.DictReader(open(out / "samples.csv")))
    j = last_json(out / "agent.log") or {}
    link = j.get("link", {})
    ok = agent_rc == 0 and j.get("keyframes_lost") == 0
    lines = [f"agent exit code {agent_rc} ({'with a server' if with_server else 'standalone'}); frames "
             f"{j.get('frames')}, tracked {j.get('tracked')}, keyframes created {j.get('keyframes_created')}, "
             f"segments {j.get('segments')}, lost {j.get('keyframes_lost')}; peak RSS "
             f"{j.get('footprint', {}).get('peak_rss_mb')} MB; CPU per frame over the flight "
             f"{j.get('footprint', {}).get('cpu_ms_per_frame', {}).get('total')} ms"]
    if with_server:
        keys = ["kfs_sent", "kfs_acked", "kfs_unacked", "kfs_persisted", "kfs_unpersisted", "kfs_resent",
                "write_failures"]
        lines.append("link: " + ", ".join(f"{k} {link.get(k)}" for k in keys))
        lines.append(f"dropped before the server saved them {j.get('keyframes_dropped_unpersisted')}")
        ok &= link.get("kfs_unacked") == 0 and link.get("write_failures") == 0
        ok &= j.get("keyframes_dropped_unpersisted") == 0
    lines += ["| minute | agent RSS MB | agent CPU ms/frame | agent cores | keyframes | unacked | backlog kB "
              "| server RSS MB | server cores |", "|---|---|---|---|---|---|---|---|---|"]
    if not rows:
        lines.append("no samples")
        ok = False
    else:
        step = max(1, len(rows) // 10)
        def cell(r, key, fmt, scale=1.0):
            v = num(r, key)
            return "" if v is None else format(v * scale, fmt)

        for r in rows[::step] + ([rows[-1]] if (len(rows) - 1) % step else []):
            cells = [cell(r, "minute", ".1f"), cell(r, "agent_rss_mb", ".1f"), cell(r, "agent_cpu_ms_per_frame", ".1f"),
                     cell(r, "agent_cpu_cores", ".2f"), cell(r, "keyframes", ".0f"), cell(r, "kfs_unacked", ".0f"),
                     cell(r, "backlog_bytes", ".1f", 1e-3), cell(r, "server_rss_mb", ".1f"),
                     cell(r, "server_cpu_cores", ".2f")]
            lines.append("| " + " | ".join(cells) + " |")
        after = [r for r in rows if float(r["minute"]) >= warmup]
        if len(after) < 6:
            ok = False
            lines.append(f"the flight ended before minute {warmup:g} + 6 samples")
        else:
            rss0, rss1 = num(after[0], "agent_rss_mb"), num(after[-1], "agent_rss_mb")
            growth = rss1 - rss0
            lines.append(f"agent RSS from minute {warmup:g} to the end: {rss0:.1f} -> {rss1:.1f} MB "
                         f"({growth:+.1f} MB; max {max(num(r, 'agent_rss_mb') for r in after):.1f}; "
                         f"allowed +{slack:g})")
            ok &= growth <= slack
            cpu0, cpu1 = tenth_median(after, "agent_cpu_ms_per_frame", False), tenth_median(
                after, "agent_cpu_ms_per_frame", True)
            if cpu0 and cpu1:
                lines.append(f"agent CPU per frame, first tenth after the warm-up -> last tenth (medians): "
                             f"{cpu0:.1f} -> {cpu1:.1f} ms ({cpu1 / cpu0:.2f}x; allowed {cpu_ratio:g}x)")
                ok &= cpu1 <= cpu_ratio * cpu0
            else:
                ok = False
                lines.append("no CPU per frame sampled")
            if with_server:
                un0, un1 = tenth_median(after, "kfs_unacked", False), tenth_median(after, "kfs_unacked", True)
                lines.append(f"unacknowledged keyframes, first -> last tenth (medians): {un0:g} -> {un1:g} "
                             f"(max {max(num(r, 'kfs_unacked') or 0 for r in after):g}; allowed first + 20)")
                ok &= un0 is not None and un1 is not None and un1 <= un0 + 20
    lines.append("PASS" if ok else "FAIL")
    (out / "long_flight.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
