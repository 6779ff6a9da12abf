#!/usr/bin/env python3
"""GET /metrics end to end (issue 32), read by Prometheus' own text-format parser.

Runs a short ccm_replay (two agents that fuse) with --http 0 and scrapes /metrics while it
runs and after it finished. Every scrape must parse (python3-prometheus-client's parser),
every family must have one type and samples; after the replay the values must equal what
/api/status and the replay's summary.json report (agents, maps, keyframes, points, fusions,
loops, global BAs, per-agent registered keyframes), queues and registration lags must be 0,
and counters must never have gone down between scrapes.
Exit 77 (skipped) if python3-prometheus-client is missing.
"""
import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from prometheus_scrape import load_parser, wait_for_url  # noqa: E402

text_string_to_metric_families = load_parser()

EXPECTED = {  # family (as the parser names it) -> type
    "ccm_server_agents": "gauge", "ccm_server_maps": "gauge", "ccm_server_keyframes": "gauge",
    "ccm_server_map_points": "gauge", "ccm_server_fusions": "counter", "ccm_server_loops": "counter",
    "ccm_server_global_bas": "counter", "ccm_server_global_ba_seconds": "counter",
    "ccm_server_keyframes_removed": "counter", "ccm_server_place_recognition_queue_keyframes": "gauge",
    "ccm_server_agent_queue_batches": "gauge", "ccm_server_agent_registration_lag_seconds": "gauge",
    "ccm_server_agent_keyframes_registered": "counter", "ccm_server_agent_keyframes": "gauge",
    "ccm_server_http_requests": "counter", "ccm_server_metrics_scrapes": "counter",
}


def fail(message):
    print("FAIL: " + message)
    sys.exit(1)


def scrape(base):
    with urllib.request.urlopen(base + "metrics", timeout=10) as r:
        if not r.headers.get("Content-Type", "").startswith("text/plain; version=0.0.4"):
            fail("content type " + r.headers.get("Content-Type", ""))
        text = r.read().decode()
    families = {}
    try:
        for f in text_string_to_metric_families(text):
            if f.name in families:
                fail("family %s twice" % f.name)
            if not f.samples:
                fail("family %s has no samples" % f.name)
            families[f.name] = f
    except ValueError as e:
        fail("the Prometheus parser refused the scrape: %s\n%s" % (e, text[:2000]))
    return families


def value(families, name, **labels):
    for s in families[name].samples:
        if all(s.labels.get(k) == v for k, v in labels.items()):
            return s.value
    fail("no sample of %s with %s" % (name, labels))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--replay", required=True)
    ap.add_argument("--vocab", required=True)
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--work", required=True)
    args = ap.parse_args()
    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    out = os.path.join(args.work, "out")
    log_path = os.path.join(args.work, "replay.log")
    proc = subprocess.Popen([args.replay, "--sim", args.scenario, "--vocab", args.vocab, "--out", out, "--http", "0",
                             "--http-linger", "-1"], stdout=open(log_path, "w"), stderr=subprocess.STDOUT)
    try:
        finished = False
        base = wait_for_url(lambda: open(log_path).read(), r"map view on (http://\S+)", proc)
        if base is None:
            fail("ccm_replay ended before serving (see %s)" % log_path)
        scrapes, previous = 0, {}
        while not finished:
            families = scrape(base)
            scrapes += 1
            for name, f in families.items():  # counters never go down
                if f.type != "counter":
                    continue
                for s in f.samples:
                    key = (s.name, tuple(sorted(s.labels.items())))
                    if s.value < previous.get(key, 0):
                        fail("counter %s went down: %s -> %s" % (key, previous[key], s.value))
                    previous[key] = s.value
            with urllib.request.urlopen(base + "api/status", timeout=10) as r:
                finished = json.loads(r.read())["host"].get("finished", False)
            time.sleep(0.5)
        families = scrape(base)
        with urllib.request.urlopen(base + "api/status", timeout=10) as r:
            status = json.loads(r.read())
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=30)
    for name, kind in EXPECTED.items():
        if name not in families:
            fail("family %s missing; got %s" % (name, sorted(families)))
        if families[name].type != kind:
            fail("%s is a %s, not a %s" % (name, families[name].type, kind))
    totals = status["totals"]
    checks = [("ccm_server_agents", totals["agents"]), ("ccm_server_maps", totals["maps"]),
              ("ccm_server_keyframes", totals["keyframes"]), ("ccm_server_map_points", totals["map_points"]),
              ("ccm_server_fusions", totals["fusions"]), ("ccm_server_loops", totals["loops"]),
              ("ccm_server_global_bas", totals["global_bas"])]
    summary = json.load(open(os.path.join(out, "summary.json")))
    checks.append(("ccm_server_maps", len(summary["maps"])))
    for name, expected in checks:
        got = value(families, name)
        if got != expected:
            fail("%s = %s, status/summary say %s" % (name, got, expected))
    for a in status["agents"]:
        agent = str(a["id"])
        got = value(families, "ccm_server_agent_keyframes_registered", agent=agent)
        if got != a["registered"] or got <= 0:
            fail("agent %s: %s keyframes registered in /metrics, %s in the status" % (agent, got, a["registered"]))
        if value(families, "ccm_server_agent_queue_batches", agent=agent) != 0:
            fail("agent %s: a queue after the replay" % agent)
        if value(families, "ccm_server_agent_registration_lag_seconds", agent=agent) != 0:
            fail("agent %s: a registration lag after the replay" % agent)
    if totals["fusions"] < 1:
        fail("the scenario's agents did not fuse")
    print("OK: %d scrapes parsed during the replay; %d families; %d agents, %d keyframes, %d fusions" %
          (scrapes, len(families), totals["agents"], totals["keyframes"], totals["fusions"]))


if __name__ == "__main__":
    main()
