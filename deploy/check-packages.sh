#!/usr/bin/env bash
# Builds the Debian packages from a built tree (cpack -G DEB) and checks them: each package
# holds what it should (dpkg-deb -c), run-time library dependencies were computed
# (dpkg-shlibdeps -> Depends), configs and units carry the final install paths, and the
# binaries of the extracted packages (dpkg -x) run and find the installed data.
#
#   deploy/check-packages.sh BUILD_DIR [OUT_DIR]
set -euo pipefail
BUILD_DIR="$(cd "${1:?usage: check-packages.sh BUILD_DIR [OUT_DIR]}" && pwd)"
OUT="${2:-$BUILD_DIR/packages}"
for tool in cpack dpkg-deb dpkg dpkg-shlibdeps; do
  command -v "$tool" >/dev/null || { echo "check-packages: '$tool' missing (apt install dpkg-dev cmake)" >&2; exit 1; }
done
fail() { echo "check-packages: FAIL: $*" >&2; exit 1; }

rm -rf "$OUT"
mkdir -p "$OUT"
start=$(date +%s)
if ! (cd "$BUILD_DIR" && cpack -G DEB -B "$OUT" >"$OUT/cpack.log" 2>&1); then
  cat "$OUT/cpack.log" >&2
  fail "cpack failed"
fi
echo "[packages] cpack took $(( $(date +%s) - start )) s"

deb_of() { ls "$OUT"/"$1"_*.deb 2>/dev/null | head -1; }
expect_files() {  # package, then paths that must be in it
  local pkg="$1"; shift
  local deb; deb="$(deb_of "$pkg")"
  [ -n "$deb" ] || fail "no $pkg package in $OUT"
  local listing; listing="$(dpkg-deb -c "$deb" | awk '{print $6}')"
  for f in "$@"; do
    grep -qx "\./${f#/}" <<<"$listing" || fail "$pkg lacks $f; it has:
$listing"
  done
  echo "[packages] $(basename "$deb"): $(wc -l <<<"$listing") entries, $(du -k "$deb" | cut -f1) kB"
}
expect_depends() {  # package, then substrings its Depends must contain
  local pkg="$1"; shift
  local depends; depends="$(dpkg-deb -f "$(deb_of "$pkg")" Depends)"
  for d in "$@"; do
    grep -q "$d" <<<"$depends" || fail "$pkg Depends lacks '$d': $depends"
  done
  echo "[packages] $pkg Depends: $depends"
}

expect_files ccm-common /usr/share/ccm-slam-dds/qos_profiles/default.xml /usr/share/ccm-slam-dds/qos_profiles/wifi.xml \
  /usr/share/ccm-slam-dds/vocabulary/default_vocab_k10_l5.ccmvoc /etc/ccm-slam-dds/wifi.xml \
  /etc/ccm-slam-dds/wifi-secure.xml /usr/share/ccm-slam-dds/scripts/make-pki.sh \
  /usr/share/ccm-slam-dds/scripts/run-discovery-server.sh /usr/share/doc/ccm-slam-dds/deployment.md
expect_files ccm-agent /usr/bin/ccm_agent /usr/lib/systemd/system/ccm-agent@.service \
  /usr/share/ccm-slam-dds/config/agent-onboard.yaml
expect_files ccm-server /usr/bin/ccm_server /usr/bin/ccm_ctl /usr/lib/systemd/system/ccm-server.service \
  /etc/ccm-slam-dds/server.yaml
expect_files ccm-tools /usr/bin/ccm_sim /usr/bin/ccm_eval /usr/bin/ccm_vocab /usr/bin/ccm_replay
# dpkg-shlibdeps found the shared libraries (Fast DDS, OpenCV, Ceres, yaml-cpp, ...).
expect_depends ccm-agent libfastrtps libopencv-core libyaml-cpp ccm-common
expect_depends ccm-server libfastrtps libopencv-core libcholmod ccm-common
expect_depends ccm-tools libopencv-imgcodecs ccm-common
dpkg-deb -I "$(deb_of ccm-server)" conffiles | grep -qx "/etc/ccm-slam-dds/server.yaml" || fail "server.yaml is not a conffile"
dpkg-deb -I "$(deb_of ccm-common)" conffiles | grep -qx "/etc/ccm-slam-dds/wifi-secure.xml" || fail "wifi-secure.xml is not a conffile"

ROOT="$OUT/root"
for pkg in ccm-common ccm-agent ccm-server ccm-tools; do dpkg -x "$(deb_of "$pkg")" "$ROOT"; done
# Paths were filled in for the real install location, not the build or staging tree.
grep -q "^ExecStart=/usr/bin/ccm_server --config /etc/ccm-slam-dds/server.yaml" "$ROOT/usr/lib/systemd/system/ccm-server.service" \
  || fail "ccm-server.service: $(grep ExecStart "$ROOT/usr/lib/systemd/system/ccm-server.service")"
grep -q "^ExecStart=/usr/bin/ccm_agent --config /etc/ccm-slam-dds/agents/%i.yaml" "$ROOT/usr/lib/systemd/system/ccm-agent@.service" \
  || fail "ccm-agent@.service: $(grep ExecStart "$ROOT/usr/lib/systemd/system/ccm-agent@.service")"
grep -q "^qos_file: /etc/ccm-slam-dds/wifi-secure.xml" "$ROOT/etc/ccm-slam-dds/server.yaml" || fail "server.yaml qos_file"
grep -q "^security_dir: /etc/ccm-slam-dds/security" "$ROOT/etc/ccm-slam-dds/server.yaml" || fail "server.yaml is not secure"
grep -q "<maxMessageSize>8192</maxMessageSize>" "$ROOT/etc/ccm-slam-dds/wifi-secure.xml" || fail "wifi-secure.xml datagrams"
if grep -rq "$BUILD_DIR\|_CPack_Packages" "$ROOT/etc" "$ROOT/usr/lib/systemd"; then fail "a build path leaked into the configs"; fi

for bin in ccm_agent ccm_server ccm_ctl ccm_sim ccm_eval ccm_vocab ccm_replay; do
  "$ROOT/usr/bin/$bin" --help >"$OUT/$bin.help" 2>&1 || fail "$bin --help exited $?: $(cat "$OUT/$bin.help")"
done
echo "[packages] --help runs for every extracted binary"
# The extracted server finds the extracted vocabulary and default QoS file (install_paths.h).
"$ROOT/usr/bin/ccm_server" --domain 191 --duration 1 --no-final-ba --log-level info >"$OUT/server_run.log" 2>&1 \
  || fail "extracted ccm_server failed: $(cat "$OUT/server_run.log")"
grep -q "vocabulary $ROOT/usr/share/ccm-slam-dds/vocabulary/default_vocab_k10_l5.ccmvoc" "$OUT/server_run.log" \
  || fail "extracted ccm_server did not use the installed vocabulary: $(grep 'server up' "$OUT/server_run.log")"
grep -q "QoS $ROOT/usr/share/ccm-slam-dds/qos_profiles/default.xml" "$OUT/server_run.log" \
  || fail "extracted ccm_server did not use the installed QoS file: $(grep 'server up' "$OUT/server_run.log")"
"$ROOT/usr/bin/ccm_vocab" info "$ROOT/usr/share/ccm-slam-dds/vocabulary/default_vocab_k10_l5.ccmvoc" >/dev/null \
  || fail "ccm_vocab cannot read the installed vocabulary"
echo "[packages] OK ($(( $(date +%s) - start )) s)"
