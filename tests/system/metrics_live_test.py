#!/usr/bin/env python3
"""Prometheus metrics of a live team (issue 32): ccm_server (--http, autosaving) and one
ccm_agent (--metrics) over DDS, both scraped while the agent flies and read by Prometheus'
own text-format parser (python3-prometheus-client).

Checks: every scrape of both parses; the agent's frame and keyframe counters grow and never go
down; what the agent reports sent, acknowledged and tracked matches what the server's scrape
says about it (the server's per-agent link facts come from the agent's heartbeat, so they may
trail by a heartbeat); the server's autosave age stays below twice the autosave period; after
the agent left, the server's registered keyframes equal /api/status. Exit 77 without the
parser.
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

DOMAIN = "197"
AUTOSAVE_S = 2.0


def fail(message, procs=()):
    for p in procs:
        if p.poll() is None:
            p.kill()
    print("FAIL: " + message)
    sys.exit(1)


def scrape(url):
    with urllib.request.urlopen(url, timeout=10) as r:
        text = r.read().decode()
    samples = {}
    for family in text_string_to_metric_families(text):
        for s in family.samples:
            samples[(s.name, tuple(sorted(s.labels.items())))] = s.value
    return samples


def get(samples, name, **labels):
    return samples.get((name, tuple(sorted(labels.items()))))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--server", required=True)
    ap.add_argument("--agent", required=True)
    ap.add_argument("--qos", required=True)
    ap.add_argument("--work", required=True)
    args = ap.parse_args()
    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    server_log, agent_log = os.path.join(args.work, "server.log"), os.path.join(args.work, "agent.log")
    server = subprocess.Popen([args.server, "--qos", args.qos, "--domain", DOMAIN, "--http", "0", "--map-file",
                               os.path.join(args.work, "stack.ccmmap"), "--autosave", str(AUTOSAVE_S),
                               "--progress", "1000"], stdout=open(server_log, "w"), stderr=subprocess.STDOUT)
    agent = subprocess.Popen([args.agent, "--agent-id", "1", "--sim", "hall3", "--sim-agent", "0", "--max-frames",
                              "400", "--rate", "realtime", "--drain", "30", "--qos", args.qos, "--domain", DOMAIN,
                              "--metrics", "0"], stdout=open(agent_log, "w"), stderr=subprocess.STDOUT)
    procs = (server, agent)
    server_url = wait_for_url(lambda: open(server_log).read(), r"map view on (http://\S+)", server)
    agent_url = wait_for_url(lambda: open(agent_log).read(), r"metrics on (http://\S+)", agent)
    if not server_url or not agent_url:
        fail("no endpoint: server %s, agent %s (logs in %s)" % (server_url, agent_url, args.work), procs)
    server_url = server_url.rstrip("/") + "/"
    last_agent, agent_scrapes, matched = {}, 0, False
    while agent.poll() is None:
        try:
            a = scrape(agent_url)
        except (OSError, ValueError) as e:
            # The agent closes its endpoint when its flight is done, a moment before it exits
            # (its summary, the DDS teardown): only an agent that stays up without it fails.
            try:
                agent.wait(timeout=20)
            except subprocess.TimeoutExpired:
                fail("agent scrape failed and the agent did not exit: %s" % e, procs)
            break
        s = scrape(server_url + "metrics")
        agent_scrapes += 1
        for key, v in a.items():
            if key[0].endswith("_total") and v < last_agent.get(key, 0):
                fail("agent counter %s went down" % (key,), procs)
        last_agent = a
        sent = get(a, "ccm_agent_keyframes_sent_total", agent="1")
        acked = get(a, "ccm_agent_keyframes_acked_total", agent="1")
        if sent is None or acked is None or acked > sent:
            fail("agent keyframes sent %s, acked %s" % (sent, acked), procs)
        if get(a, "ccm_agent_tracking_state", agent="1", state="tracking") == 1 and \
                get(a, "ccm_agent_frames_tracked_total", agent="1") == 0:
            fail("tracking with no tracked frame", procs)
        server_sent = get(s, "ccm_server_agent_keyframes_sent_total", agent="1")
        if server_sent is not None and server_sent > sent:
            fail("the server says agent 1 sent %s keyframes, the agent %s" % (server_sent, sent), procs)
        matched |= server_sent is not None and server_sent > 0
        age = get(s, "ccm_server_autosave_age_seconds")
        if age is not None and age > 2 * AUTOSAVE_S + 1:
            fail("autosave age %s s with a %s s period" % (age, AUTOSAVE_S), procs)
        time.sleep(1.0)
    if agent.wait() != 0:
        fail("ccm_agent exited with %s (log %s)" % (agent.returncode, agent_log), procs)
    frames = get(last_agent, "ccm_agent_frames_total", agent="1")
    if agent_scrapes < 5 or not frames or frames < 100:
        fail("only %d agent scrapes, %s frames" % (agent_scrapes, frames), procs)
    if not matched:
        fail("the server never reported the agent's keyframes from its heartbeat", procs)
    s = scrape(server_url + "metrics")
    with urllib.request.urlopen(server_url + "api/status", timeout=10) as r:
        status = json.loads(r.read())
    registered = get(s, "ccm_server_agent_keyframes_registered_total", agent="1")
    expected = next(a["registered"] for a in status["agents"] if a["id"] == 1)
    if registered != expected or registered < 10:
        fail("server: %s keyframes registered in /metrics, %s in /api/status" % (registered, expected), procs)
    if get(s, "ccm_server_autosave_age_seconds") is None:
        fail("no autosave age in the server's metrics", procs)
    server.send_signal(signal.SIGTERM)
    if server.wait(timeout=60) != 0:
        fail("ccm_server exited with %s" % server.returncode)
    print("OK: %d scrapes of each; agent: %d frames, %d keyframes sent, %d acked; server: %d registered" %
          (agent_scrapes, frames, get(last_agent, "ccm_agent_keyframes_sent_total", agent="1"),
           get(last_agent, "ccm_agent_keyframes_acked_total", agent="1"), registered))


if __name__ == "__main__":
    main()
