# Sourced by long_flight.sh and tests/bench/long_mission.sh: hall3 with every agent's closed
# loop flown for a whole long flight (the simulator repeats a closed path).
#   write_long_hall3 BIN FILE SECONDS
write_long_hall3() {
  local bin="$1" file="$2" seconds="$3"
  "$bin/tests/sim/ccm_sim" --dump hall3 >"$file"
  python3 - "$file" "$seconds" <<'PY'
import re, sys
path, seconds = sys.argv[1], sys.argv[2]
text = open(path).read()
text = re.sub(r"duration_s: [0-9.]+", f"duration_s: {seconds}", text)  # every agent's
open(path, "w").write(text)
PY
  [ "$(grep -c "duration_s: $seconds\$" "$file")" -eq 3 ] || { echo "could not set the flight's duration in $file"; return 2; }
}
