#!/usr/bin/env bash
# Runs a Fast DDS discovery server for a ccm-slam-dds team (docs/deployment.md, "Discovery
# server"). Agents, server and ccm_ctl use the `ccm_participant_ds_client` profile of
# wifi.xml, which points at this server; it then relays discovery between them over unicast,
# so nothing needs multicast and no participant has to list the others' addresses.
#
#   deploy/run-discovery-server.sh [--ip ADDRESS] [--port PORT] [--id N]
#
# Defaults: --ip 0.0.0.0 (every interface), --port 11811, --id 0 (the prefix wifi.xml's
# client profile expects: 44.53.00.5f.45.50.52.4f.53.49.4d.41). Runs in the foreground
# (exec), so systemd or a test can stop it with SIGTERM/SIGINT. Needs `fastdds`
# (Debian: fastdds-tools).
set -euo pipefail
IP="0.0.0.0"
PORT=11811
ID=0
while [ $# -gt 0 ]; do
  case "$1" in
    --ip) IP="$2"; shift 2 ;;
    --port) PORT="$2"; shift 2 ;;
    --id) ID="$2"; shift 2 ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) echo "run-discovery-server.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
# `fastdds discovery` is a Python wrapper around fast-discovery-server that does not pass
# SIGTERM on (its child would outlive it): exec the binary itself when it is there, so the
# caller's pid is the server's.
if command -v fast-discovery-server >/dev/null; then
  exec fast-discovery-server -i "$ID" -l "$IP" -p "$PORT"
fi
command -v fastdds >/dev/null || { echo "run-discovery-server.sh: 'fastdds' not found (apt install fastdds-tools)" >&2; exit 1; }
exec fastdds discovery -i "$ID" -l "$IP" -p "$PORT"
