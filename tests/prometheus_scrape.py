"""Shared by the tests that read /metrics with Prometheus' own parser
(tests/server_runtime/metrics_scrape_test.py, tests/system/metrics_live_test.py)."""
import os
import re
import sys
import time


def load_parser():
    """prometheus_client's text_string_to_metric_families, or exit 77 (skip) without it."""
    try:
        from prometheus_client.parser import text_string_to_metric_families
        return text_string_to_metric_families
    except ImportError:
        # Debian's package lives in the system interpreter's dist-packages; a python3 earlier
        # in PATH (pyenv, a venv) does not see it.
        system = "/usr/bin/python3"
        if os.path.exists(system) and os.path.realpath(sys.executable) != os.path.realpath(system):
            os.execv(system, [system] + sys.argv)
        print("python3-prometheus-client not installed (deploy/install-deps.sh installs it); test skipped")
        sys.exit(77)


def wait_for_url(read_output, pattern, proc, timeout_s=60):
    """The first group of `pattern` in the process' output (read_output() returns it so
    far), or None if the process ends or the time runs out first."""
    deadline = time.time() + timeout_s
    while time.time() < deadline:
        m = re.search(pattern, read_output())
        if m:
            return m.group(1)
        if proc.poll() is not None:
            return None
        time.sleep(0.2)
    return None
