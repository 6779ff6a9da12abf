#!/usr/bin/env python3
"""The live map view end to end (issue 14).

Drives a short ccm_replay (two agents in one room that fuse) with --http 0 and, while it
runs, follows the map the way the page does (deltas since the version it holds); at the end
that mirror must equal the full map. Once the replay is done: the API's totals must match
the replay's summary.json; headless Chromium opens the page, waits for its updates and the
page's status element must show the agents, keyframes and fusions the server reports; a
screenshot is saved (map_view.png in the work folder). Bad requests must get a 4xx JSON
error and leave the server running; SIGTERM must end it cleanly.
Exit 77 (skipped) if chromium is not installed.
"""
import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
                  "--enable-unsafe-swiftshader", "--hide-scrollbars", "--window-size=1280,800"]


def fail(message):
    print("FAIL: " + message)
    sys.exit(1)


def get(url):
    """(status, parsed JSON body) of a GET; 4xx/5xx answers are returned, not raised."""
    try:
        with urllib.request.urlopen(url, timeout=10) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


class Mirror:
    """What a client holds after applying /api/map deltas."""

    def __init__(self):
        self.keyframes, self.points, self.edges, self.version = {}, {}, {}, 0

    def apply(self, m):
        if m["reset"]:
            self.keyframes, self.points, self.edges = {}, {}, {}
        for i in m["removed"]["keyframes"]:
            self.keyframes.pop(i, None)
        for i in m["removed"]["points"]:
            self.points.pop(i, None)
        for a, b in m["removed"]["edges"]:
            self.edges.pop(a + "|" + b, None)
        for k in m["keyframes"]:
            self.keyframes[k[0]] = k
        for p in m["points"]:
            self.points[p[0]] = p
        for e in m["edges"]:
            self.edges[e[0] + "|" + e[1]] = e
        self.version = m["version"]


def chromium(args, url, work):
    cmd = [args.chromium] + CHROMIUM_FLAGS + ["--user-data-dir=" + os.path.join(work, "chromium-profile")]
    return cmd + ["--virtual-time-budget=6000"] + ([url] if url else [])


def check_page(args, base, status, summary):
    dom = subprocess.run(chromium(args, None, args.work) + ["--dump-dom", base + "?top=1"], capture_output=True,
                         text=True, timeout=90).stdout
    tag = re.search(r'<div id="view-status"[^>]*>', dom)
    if not tag:
        fail("the page has no view-status element; DOM starts: " + dom[:300])
    data = dict(re.findall(r'data-([a-z-]+)="([^"]*)"', tag.group(0)))
    print("page shows:", data)
    if int(data.get("updates", "0") or 0) < 1:
        fail("the page never got an update from the API")
    totals = status["totals"]
    for key, expected in (("agents", totals["agents"]), ("keyframes", totals["keyframes"]),
                          ("fusions", totals["fusions"]), ("maps", totals["maps"])):
        if int(data[key]) != expected:
            fail(f"page shows {key} = {data[key]}, the server reports {expected}")
    if totals["fusions"] != summary["fusions"] or totals["fusions"] < 1:
        fail(f"fusions: API {totals['fusions']}, summary.json {summary['fusions']} (expected the agents to fuse)")
    if data.get("webgl") != "1":
        print("note: no WebGL in this Chromium; the 3-D view is empty, the panel still checked")
    shot = os.path.join(args.work, "map_view.png")
    subprocess.run(chromium(args, None, args.work) + ["--screenshot=" + shot, base + "?top=1"],
                   capture_output=True, timeout=90)
    with open(shot, "rb") as f:
        head = f.read(8)
    if head != b"\x89PNG\r\n\x1a\n" or os.path.getsize(shot) < 10000:
        fail("no usable screenshot at " + shot)
    print("screenshot:", shot, os.path.getsize(shot), "bytes")


def check_bad_requests(base):
    bad = ["api/nope", "nope.html", "api/map?since=abc", "api/map?since=-3", "api/map?since=123456789012",
           "api/map?since=99999999999999999999999999", "api/map?min_weight=1e9", "api/map?since=0&since=1",
           "api/map?what=1", "api/events?since=100000", "api/events?limit=0", "api/events?limit=999999999",
           "api/status?x=1", "three/../../../etc/passwd", "api/map?since=%00"]
    for path in bad:
        code, body = get(base + path)
        if not 400 <= code < 500 or not body.get("error"):
            fail(f"GET /{path} answered {code} {body}")
    long_path = base + "api/map?since=" + "9" * 20000
    try:
        urllib.request.urlopen(long_path, timeout=10)
        fail("a 20 kB URL was accepted")
    except urllib.error.HTTPError as e:
        if not 400 <= e.code < 500:
            fail(f"a 20 kB URL got {e.code}")
    req = urllib.request.Request(base + "api/status", data=b"x", method="POST")
    try:
        urllib.request.urlopen(req, timeout=10)
        fail("POST was accepted")
    except urllib.error.HTTPError as e:
        if e.code != 405:
            fail(f"POST got {e.code}, expected 405")
    code, _ = get(base + "api/status")
    if code != 200:
        fail("the server stopped answering after the bad requests")
    print(f"{len(bad) + 2} bad requests: each a 4xx with an error message; server still up")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--replay", required=True)
    ap.add_argument("--vocab", required=True)
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--chromium", default=shutil.which("chromium") or "")
    args = ap.parse_args()
    if not args.chromium:
        print("chromium not installed (apt-get install chromium): skipped")
        sys.exit(77)
    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    out = os.path.join(args.work, "out")
    log = open(os.path.join(args.work, "replay.log"), "w+")
    t0 = time.time()
    proc = subprocess.Popen([args.replay, "--sim", args.scenario, "--vocab", args.vocab, "--out", out, "--http", "0",
                             "--http-linger", "-1"], stdout=subprocess.PIPE, stderr=log, text=True)
    try:
        base = None
        while base is None:
            line = proc.stdout.readline()
            if not line:
                fail("ccm_replay ended before serving the map view")
            m = re.search(r"map view on (http://\S+)", line)
            if m:
                base = m.group(1)
        # Follow the map while the replay runs, as the page does.
        finished = threading.Event()

        def read_rest():
            for rest in proc.stdout:
                if "map view stays on" in rest:
                    finished.set()

        threading.Thread(target=read_rest, daemon=True).start()
        mirror, polls, versions, done = Mirror(), 0, set(), False
        while not done:
            if proc.poll() is not None:
                fail("ccm_replay exited during the run; see " + log.name)
            done = finished.is_set()
            code, delta = get(f"{base}api/map?since={mirror.version}")
            if code != 200:
                fail(f"delta request failed: {code} {delta}")
            if delta["version"] < mirror.version:
                fail("the version went backwards")
            mirror.apply(delta)
            versions.add(delta["version"])
            polls += 1
            time.sleep(0.5)
        print(f"replay done in {time.time() - t0:.0f} s; followed {polls} polls over {len(versions)} versions")
        # Compare at one version: the snapshot thread may still publish one after the replay's
        # last words (its final global BA), between a full fetch and a delta fetch.
        for _ in range(20):
            code, delta = get(f"{base}api/map?since={mirror.version}")
            mirror.apply(delta)
            code, full = get(base + "api/map?since=0")
            final = Mirror()
            final.apply(full)
            if full["version"] == delta["version"]:
                break
            time.sleep(0.5)
        else:
            fail("the map view never held still for two requests")
        if (mirror.keyframes, mirror.points, mirror.edges) != (final.keyframes, final.points, final.edges):
            fail("the deltas did not add up to the full map "
                 f"({len(mirror.keyframes)}/{len(final.keyframes)} KFs, {len(mirror.points)}/{len(final.points)} points)")
        if len(versions) < 3:
            fail(f"the map changed only {len(versions)} times during the replay")
        print(f"deltas add up to the full map: {len(final.keyframes)} keyframes, {len(final.points)} points, "
              f"{len(final.edges)} edges")

        _, status = get(base + "api/status")
        with open(os.path.join(out, "summary.json")) as f:
            summary = json.load(f)
        map_kfs = sum(m["keyframes"] for m in summary["maps"])
        if status["totals"]["keyframes"] != map_kfs or status["totals"]["keyframes"] != len(final.keyframes):
            fail(f"keyframes: API {status['totals']['keyframes']}, map {len(final.keyframes)}, summary.json {map_kfs}")
        if status["totals"]["maps"] != len(summary["maps"]):
            fail(f"maps: API {status['totals']['maps']}, summary.json {len(summary['maps'])}")
        check_page(args, base, status, summary)
        check_bad_requests(base)
        _, status = get(base + "api/status")
        print("http counters:", status["http"], "snapshot:", status["snapshot"])
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
        try:
            code = proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            fail("ccm_replay did not stop on SIGTERM")
    if code != 0:
        fail(f"ccm_replay exited with {code} after SIGTERM")
    print(f"OK in {time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
