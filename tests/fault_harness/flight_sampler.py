#!/usr/bin/env python3
"""Samples a long flight's processes until the agent exits (used by long_flight.sh).

Every SAMPLE_S seconds one row goes to OUT.csv: the agent's and the server's resident memory
(/proc/PID/status VmRSS), their CPU over the interval (/proc/PID/stat utime + stime), and the
agent's Prometheus counters (frames, keyframes, unacknowledged keyframes, backlog bytes) read
from its --metrics endpoint with Prometheus' own parser (tests/prometheus_scrape.py). CPU per
frame is the agent's CPU over the interval divided by the frames it processed in that
interval, so a slower day moves the level, not the slope.

usage: flight_sampler.py OUT.csv SAMPLE_S AGENT_PID METRICS_URL [SERVER_PID]
"""
import csv
import os
import sys
import time
import urllib.request

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from prometheus_scrape import load_parser  # noqa: E402  (Prometheus' own parser of the text format)

TICKS = os.sysconf("SC_CLK_TCK")
METRICS = {
    "ccm_agent_frames_total": "frames",
    "ccm_agent_keyframes_created_total": "keyframes",
    "ccm_agent_keyframes_unacked": "kfs_unacked",
    "ccm_agent_backlog_bytes": "backlog_bytes",
}


def rss_mb(pid):
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


def cpu_s(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()  # after "(comm)": state is field 3
        return (int(fields[11]) + int(fields[12])) / TICKS  # utime, stime (fields 14, 15)
    except (OSError, IndexError, ValueError):
        return None


def scrape(url, parse):
    values = {}
    try:
        with urllib.request.urlopen(url, timeout=2) as r:
            for family in parse(r.read().decode()):
                for sample in family.samples:
                    if sample.name in METRICS:
                        values[METRICS[sample.name]] = sample.value
    except (OSError, ValueError):
        pass
    return values


def alive(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def main():
    out, sample_s, agent, url = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
    server = int(sys.argv[5]) if len(sys.argv) > 5 else None
    parse = load_parser()
    cols = ["minute", "agent_rss_mb", "server_rss_mb", "agent_cpu_ms_per_frame", "agent_cpu_cores",
            "server_cpu_cores", "frames", "keyframes", "kfs_unacked", "backlog_bytes"]
    start = time.monotonic()
    last = None  # (time, agent cpu, server cpu, frames)
    with open(out, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        while alive(agent):
            time.sleep(sample_s)
            now, a_cpu = time.monotonic(), cpu_s(agent)
            s_cpu = cpu_s(server) if server else None
            m = scrape(url, parse)
            if a_cpu is None or "frames" not in m:
                continue
            row = {"minute": round((now - start) / 60.0, 2), "agent_rss_mb": rss_mb(agent),
                   "server_rss_mb": rss_mb(server) if server else "", **m}
            if last:
                dt, dframes = now - last[0], m["frames"] - last[3]
                row["agent_cpu_cores"] = round((a_cpu - last[1]) / dt, 3)
                if dframes > 0:
                    row["agent_cpu_ms_per_frame"] = round(1000.0 * (a_cpu - last[1]) / dframes, 2)
                if s_cpu is not None and last[2] is not None:
                    row["server_cpu_cores"] = round((s_cpu - last[2]) / dt, 3)
            last = (now, a_cpu, s_cpu, m["frames"])
            w.writerow([row.get(c, "") for c in cols])
            f.flush()


if __name__ == "__main__":
    main()
