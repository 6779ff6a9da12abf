#!/usr/bin/env bash
# From nothing to arm64 Debian packages of the onboard agent, on a Debian 12 amd64 machine
# (docs/deployment.md, "arm64 cross build"):
#   1. host tools from Debian (crossbuild-essential-arm64, mmdebstrap, qemu-user-static,
#      fastddsgen, cmake, dpkg-dev, file), only those missing
#   2. OUT_DIR/sysroot: Debian 12 arm64 -dev packages, not installed into the host
#      (deploy/make-arm64-sysroot.sh; reused when it exists)
#   3. OUT_DIR/build: configure with cmake/toolchain-aarch64-sysroot.cmake, -DCCM_AGENT_ONLY=ON
#   4. build ccm_agent (aarch64)
#   5. OUT_DIR/packages: cpack -G DEB, ccm-common and ccm-agent for arm64, dependencies from
#      dpkg-shlibdeps against the sysroot's arm64 packages
#   6. checks: the packages are arm64, `dpkg -i` installs them (dependencies checked) against the
#      sysroot's arm64 package database into a scratch root, the agent starts under qemu (--help)
#
#   deploy/cross-build-arm64.sh OUT_DIR        (JOBS=N compile jobs, default: nproc)
# Then deploy/check-arm64-agent.sh OUT_DIR runs the arm64 agent on a flight (ctest -L cross).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ $# -ge 1 ] || { echo "usage: deploy/cross-build-arm64.sh OUT_DIR" >&2; exit 2; }
mkdir -p "$1"
OUT="$(cd "$1" && pwd)"
SYSROOT="$OUT/sysroot"
BUILD="$OUT/build"
PKGS="$OUT/packages"
JOBS="${JOBS:-$(nproc)}"
say() { echo "[arm64] $*"; }
die() { echo "cross-build-arm64: ERROR: $*" >&2; exit 1; }
t0=$SECONDS

say "1. host tools"
HOST_PACKAGES=(cmake make pkg-config fastddsgen crossbuild-essential-arm64 mmdebstrap qemu-user-static
  dpkg-dev file)
missing=()
for p in "${HOST_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || die "need root or sudo to install: ${missing[*]}"
    SUDO="sudo"
  fi
  say "   installing: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" || die "apt-get install ${missing[*]}"
else
  say "   all ${#HOST_PACKAGES[@]} present"
fi

say "2. arm64 sysroot $SYSROOT"
t=$SECONDS
"$ROOT/deploy/make-arm64-sysroot.sh" "$SYSROOT" || die "sysroot (deploy/make-arm64-sysroot.sh)"
say "   sysroot ready ($((SECONDS - t)) s)"

say "3. configure $BUILD (cmake/toolchain-aarch64-sysroot.cmake, CCM_AGENT_ONLY)"
cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DCCM_AGENT_ONLY=ON \
  -DCMAKE_TOOLCHAIN_FILE="$ROOT/cmake/toolchain-aarch64-sysroot.cmake" -DCCM_ARM64_SYSROOT="$SYSROOT" \
  >"$OUT/configure.log" 2>&1 || { tail -30 "$OUT/configure.log"; die "configure failed (log: $OUT/configure.log)"; }

say "4. build ccm_agent (-j$JOBS)"
t=$SECONDS
cmake --build "$BUILD" -j "$JOBS" --target ccm_agent >"$OUT/build.log" 2>&1 \
  || { grep -m20 -B2 -A8 "error" "$OUT/build.log" || tail -30 "$OUT/build.log"; die "build failed (log: $OUT/build.log)"; }
AGENT="$BUILD/agent_runtime/ccm_agent"
file -L "$AGENT" | grep -q "ARM aarch64" || die "$AGENT is not an aarch64 executable: $(file -L "$AGENT")"
say "   ccm_agent built in $((SECONDS - t)) s: $(file -L "$AGENT" | cut -d: -f2 | cut -d, -f1-2)"

say "5. Debian packages into $PKGS"
rm -rf "$PKGS"
mkdir -p "$PKGS"
(cd "$BUILD" && cpack -G DEB -B "$PKGS") >"$OUT/cpack.log" 2>&1 \
  || { tail -30 "$OUT/cpack.log"; die "cpack failed (log: $OUT/cpack.log)"; }
rm -rf "$PKGS/_CPack_Packages"
debs=("$PKGS"/ccm-common_*_arm64.deb "$PKGS"/ccm-agent_*_arm64.deb)
for d in "${debs[@]}"; do
  [ -f "$d" ] || die "cpack made no $(basename "$d") (log: $OUT/cpack.log)"
  [ "$(dpkg-deb --field "$d" Architecture)" = arm64 ] || die "$(basename "$d") is not arm64"
  say "   $(basename "$d") $(du -k "$d" | cut -f1) KiB; Depends: $(dpkg-deb --field "$d" Depends)"
done
dpkg-deb --field "$PKGS"/ccm-agent_*_arm64.deb Depends | grep -q "libopencv-core406" \
  || die "ccm-agent has no dpkg-shlibdeps dependencies (log: $OUT/cpack.log)"

say "6. checks"
# A real `dpkg -i` (unpack and configure, dependencies checked) of both packages into a scratch
# root, against a copy of the sysroot's database (Debian's arm64 packages that
# make-arm64-sysroot.sh unpacked): a missing or unsatisfiable dependency fails it.
# (`dpkg --root --dry-run -i` would not do: it stops before the dependency check.)
CHK="$OUT/install-check"
rm -rf "$CHK"
mkdir -p "$CHK/root"
cp -a "$SYSROOT/var/lib/dpkg" "$CHK/admin"
dpkg --force-not-root --instdir="$CHK/root" --admindir="$CHK/admin" -i "${debs[@]}" >"$OUT/install-check.log" 2>&1 \
  || { cat "$OUT/install-check.log"; die "the packages do not install into the arm64 root (log: $OUT/install-check.log)"; }
for p in ccm-common ccm-agent; do
  dpkg-query --admindir="$CHK/admin" -W -f='${Status}' "$p:arm64" | grep -q "install ok installed" \
    || die "$p is not installed after dpkg -i (log: $OUT/install-check.log)"
done
[ -x "$CHK/root/usr/bin/ccm_agent" ] || die "dpkg -i did not install /usr/bin/ccm_agent"
say "   dpkg -i into a scratch root with the sysroot's arm64 package database: both installed, dependencies satisfied"
if command -v qemu-aarch64-static >/dev/null; then
  qemu-aarch64-static -L "$SYSROOT" "$AGENT" --help >/dev/null || die "the arm64 ccm_agent does not run under qemu"
  say "   qemu-aarch64-static -L sysroot ccm_agent --help: runs"
fi
say "done in $((SECONDS - t0)) s: $PKGS"
