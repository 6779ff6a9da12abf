#!/usr/bin/env bash
# Runs the steps of docs/deployment.md that a build machine can run, on a built tree:
#  1. `cmake --install` into a scratch root (prefix /usr, DESTDIR): binaries, data, configs, units
#  2. the systemd units pass `systemd-analyze verify` (when systemd-analyze exists)
#  3. the ground station: the installed ccm_server with the installed server.yaml (paths moved
#     into the scratch root) refuses to start without its DDS-Security files (secure by
#     default); with a PKI from the installed make-pki.sh it runs over wifi-secure.xml,
#     `ccm_ctl status` reads it with the operator's certificate, SIGTERM saves its map stack
#  4. the robot: the installed onboard config template loads in the installed ccm_agent
#  5. the lean onboard build (-DCCM_AGENT_ONLY=ON) configures without server, tools or tests
#  6. the arm64 cross build configures (deploy/cross-configure-arm64.sh) when
#     aarch64-linux-gnu-g++ is installed; otherwise says what is missing
# What needs a real machine (systemctl start, a camera, a second host) is not run.
#
#   deploy/check-deployment.sh BUILD_DIR [SCRATCH_DIR]
set -euo pipefail
ROOT_SRC="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="$(cd "${1:?usage: check-deployment.sh BUILD_DIR [SCRATCH_DIR]}" && pwd)"
SCRATCH="${2:-$BUILD_DIR/deployment-check}"
DOMAIN="${CCM_CHECK_DOMAIN:-192}"
fail() { echo "check-deployment: FAIL: $*" >&2; exit 1; }
rm -rf "$SCRATCH"
mkdir -p "$SCRATCH"
R="$SCRATCH/root"

echo "[deploy] 1. cmake --install (prefix /usr, DESTDIR=$R)"
DESTDIR="$R" cmake --install "$BUILD_DIR" --prefix /usr >"$SCRATCH/install.log" 2>&1 || { cat "$SCRATCH/install.log"; fail "install"; }
for f in usr/bin/ccm_agent usr/bin/ccm_server usr/bin/ccm_ctl usr/bin/ccm_sim usr/bin/ccm_eval usr/bin/ccm_vocab \
         usr/bin/ccm_replay usr/share/ccm-slam-dds/qos_profiles/wifi.xml usr/share/ccm-slam-dds/qos_profiles/default.xml \
         usr/share/ccm-slam-dds/vocabulary/default_vocab_k10_l5.ccmvoc usr/share/ccm-slam-dds/config/agent-onboard.yaml \
         usr/share/ccm-slam-dds/scripts/run-discovery-server.sh usr/share/ccm-slam-dds/scripts/make-pki.sh \
         etc/ccm-slam-dds/wifi.xml etc/ccm-slam-dds/wifi-secure.xml etc/ccm-slam-dds/server.yaml \
         usr/lib/systemd/system/ccm-server.service usr/lib/systemd/system/ccm-agent@.service; do
  [ -e "$R/$f" ] || fail "cmake --install did not install /$f"
done

echo "[deploy] 2. systemd units"
if command -v systemd-analyze >/dev/null; then
  # verify checks that ExecStart's binary exists: point it at the scratch root's.
  mkdir -p "$SCRATCH/units"
  for u in ccm-server.service ccm-agent@.service; do
    sed "s|=/usr/bin/|=$R/usr/bin/|" "$R/usr/lib/systemd/system/$u" >"$SCRATCH/units/${u/@/@robot1}"
  done
  for u in "$SCRATCH"/units/*.service; do
    out="$(systemd-analyze verify --man=no "$u" 2>&1)" || fail "systemd-analyze verify $u: $out"
    # verify exits 0 on unknown keys and only prints them.
    [ -z "$out" ] || fail "systemd-analyze verify $(basename "$u"): $out"
  done
  echo "[deploy]    systemd-analyze verify: both units clean"
else
  echo "[deploy]    systemd-analyze not installed: units not verified"
fi

echo "[deploy] 3. ground station: installed ccm_server with the installed server.yaml"
sed -e "s|/etc/ccm-slam-dds|$R/etc/ccm-slam-dds|" -e "s|/var/lib/ccm-slam-dds|$SCRATCH/var|" \
  "$R/etc/ccm-slam-dds/server.yaml" >"$SCRATCH/server.yaml"
QOS="$R/etc/ccm-slam-dds/wifi-secure.xml"
grep -q "^security_dir: $R/etc/ccm-slam-dds/security$" "$SCRATCH/server.yaml" || fail "server.yaml is not secure by default"
code=0
"$R/usr/bin/ccm_server" --config "$SCRATCH/server.yaml" --domain "$DOMAIN" --duration 5 >"$SCRATCH/nosec.log" 2>&1 || code=$?
[ "$code" != 0 ] && grep -q "$R/etc/ccm-slam-dds/security" "$SCRATCH/nosec.log" \
  || fail "without security files the server must refuse to start, naming the directory: $(cat "$SCRATCH/nosec.log")"
"$R/usr/share/ccm-slam-dds/scripts/make-pki.sh" "$SCRATCH/pki" --agents 1 >"$SCRATCH/pki.log" 2>&1 \
  || fail "make-pki.sh: $(cat "$SCRATCH/pki.log")"
cp -r "$SCRATCH/pki/server" "$R/etc/ccm-slam-dds/security"
echo "[deploy]    without security files: refused; PKI made with the installed make-pki.sh"
"$R/usr/bin/ccm_server" --config "$SCRATCH/server.yaml" --domain "$DOMAIN" --no-final-ba >"$SCRATCH/server.log" 2>&1 &
server_pid=$!
trap 'kill "$server_pid" 2>/dev/null || true' EXIT
ok=0
for _ in 1 2 3 4 5 6 7 8 9 10; do
  if "$R/usr/bin/ccm_ctl" status --qos "$QOS" --domain "$DOMAIN" --security-dir "$SCRATCH/pki/ctl" --timeout 2 \
    >"$SCRATCH/status.txt" 2>&1; then ok=1; break; fi
  sleep 0.5
done
[ "$ok" = 1 ] || fail "ccm_ctl status did not reach the installed server: $(cat "$SCRATCH/status.txt") $(cat "$SCRATCH/server.log")"
grep -q "map file $SCRATCH/var/map_stack.ccmmap" "$SCRATCH/status.txt" || fail "status: $(cat "$SCRATCH/status.txt")"
kill -TERM "$server_pid"
code=0; wait "$server_pid" || code=$?
trap - EXIT
[ "$code" = 0 ] || fail "ccm_server exited $code on SIGTERM: $(cat "$SCRATCH/server.log")"
[ -f "$SCRATCH/var/map_stack.ccmmap" ] || fail "no map stack saved on SIGTERM: $(cat "$SCRATCH/server.log")"
grep -q "vocabulary $R/usr/share/ccm-slam-dds/vocabulary/" "$SCRATCH/server.log" || fail "installed vocabulary not used"
echo "[deploy]    secure server ran, ccm_ctl status answered with the operator's certificate, SIGTERM saved the map stack"

echo "[deploy] 4. robot: the onboard template in the installed ccm_agent"
mkdir -p "$SCRATCH/agents"
sed "s|/etc/ccm-slam-dds|$R/etc/ccm-slam-dds|" "$R/usr/share/ccm-slam-dds/config/agent-onboard.yaml" >"$SCRATCH/agents/robot1.yaml"
# No camera here: the simulator stands in for it (same config otherwise), standalone.
"$R/usr/bin/ccm_agent" --config "$SCRATCH/agents/robot1.yaml" --sim hall3 --max-frames 30 --standalone \
  >"$SCRATCH/agent.log" 2>&1 || fail "ccm_agent with the onboard config: $(tail -5 "$SCRATCH/agent.log")"
echo "[deploy]    ccm_agent -c agents/robot1.yaml ran"

echo "[deploy] 5. lean onboard build configures (CCM_AGENT_ONLY)"
cmake -S "$ROOT_SRC" -B "$SCRATCH/agent-only" -DCCM_AGENT_ONLY=ON >"$SCRATCH/agent-only.log" 2>&1 \
  || { cat "$SCRATCH/agent-only.log"; fail "agent-only configure"; }
targets="$(cmake --build "$SCRATCH/agent-only" --target help)"
grep -q "ccm_agent$" <<<"$targets" || fail "agent-only tree has no ccm_agent target"
for t in ccm_server ccm_ctl ccm_sim ccm_replay system_test; do
  ! grep -q "\.\.\. $t$" <<<"$targets" || fail "agent-only tree builds $t"
done
echo "[deploy]    agent-only tree: ccm_agent, no server/tools/tests"

echo "[deploy] 6. arm64 cross build (cmake/toolchain-aarch64-debian.cmake)"
if command -v aarch64-linux-gnu-g++ >/dev/null; then
  missing=()
  for p in $("$ROOT_SRC/deploy/cross-configure-arm64.sh" --print-packages); do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if BUILD_DIR="$SCRATCH/arm64" "$ROOT_SRC/deploy/cross-configure-arm64.sh" >"$SCRATCH/arm64.log" 2>&1; then
    echo "[deploy]    arm64 configure OK"
  elif [ ${#missing[@]} -gt 0 ] && grep -q "Check for working CXX compiler: .*aarch64-linux-gnu-g++" "$SCRATCH/arm64.log"; then
    # The toolchain works (CMake compiled and linked an aarch64 program); the libraries are not there.
    echo "[deploy]    arm64 toolchain OK, configure stops at the first missing arm64 package; not installed: ${missing[*]}"
  else
    tail -20 "$SCRATCH/arm64.log"
    fail "arm64 configure (toolchain or packages)"
  fi
else
  echo "[deploy]    SKIPPED: aarch64-linux-gnu-g++ not installed (apt install g++-aarch64-linux-gnu + arm64 -dev packages, docs/deployment.md)"
fi
"$R/usr/share/ccm-slam-dds/scripts/run-discovery-server.sh" --help >/dev/null || fail "run-discovery-server.sh --help"
echo "[deploy] OK"
