#!/usr/bin/env bash
# The verdict of a live ThreadSanitizer step (tsan-live-run.sh, tsan-fleet-run.sh): prints the
# reports its processes wrote (DIR/tsan.<pid>, TSAN_OPTIONS log_path) and exits 1 if any.
# Usage: tsan-reports.sh DIR
if compgen -G "$1/tsan.*" >/dev/null; then
  echo "ThreadSanitizer reports:"
  cat "$1"/tsan.*
  exit 1
fi
