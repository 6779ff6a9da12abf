#!/usr/bin/env bash
# Builds a Debian 12 (bookworm) arm64 sysroot with the -dev packages ccm_agent links, from
# Debian's own arm64 packages, without installing anything arm64 into the host (the arm64
# -dev packages are not co-installable with the amd64 ones: docs/deployment.md):
#   1. mmdebstrap --variant=extract: downloads the packages and their dependencies and unpacks
#      them; no maintainer script runs (nothing arm64 is executed, no binfmt needed)
#   2. merged /usr as on an installed Debian 12 (/bin, /sbin, /lib -> usr/...), so that
#      /lib/ld-linux-aarch64.so.1 and the linker scripts' /lib/... paths resolve
#   3. a dpkg database (var/lib/dpkg: status, *.list, *.shlibs, *.symbols, scripts) written
#      from the downloaded .debs' control data, as dpkg would after unpacking them, so that
#      dpkg-shlibdeps finds the arm64 libraries' packages and `dpkg --root` checks dependencies
#      against it (deploy/cross-build-arm64.sh)
#   4. the alternatives the packages' postinst would register (libblas.so.3 -> ATLAS or
#      reference BLAS, liblapack.so.3: Ceres' SuiteSparse needs them), update-alternatives --root
#   5. absolute symlinks (usr/lib/aarch64-linux-gnu/libz.so -> /lib/...) made relative, so they
#      resolve inside the sysroot rather than on the host
#   6. absolute /usr paths in the packages' CMake config files prefixed with ${CMAKE_SYSROOT}
# Reuses an existing complete sysroot with the same package list (stamp file .ccm-sysroot).
#
#   deploy/make-arm64-sysroot.sh SYSROOT        (root or sudo: mmdebstrap --mode=root)
#   deploy/make-arm64-sysroot.sh --print-packages
# CCM_DEBIAN_MIRROR (default http://deb.debian.org/debian) and CCM_DEBIAN_SECURITY_MIRROR
# choose the archive.
set -euo pipefail
# What the agent links (top-level CMakeLists.txt find_package calls) plus the C/C++ runtime.
# libopencv-dev is the whole OpenCV: its CMake config checks that every module's library exists.
ARM64_PACKAGES=(libc6-dev libstdc++-12-dev libfastrtps-dev libfastcdr-dev libeigen3-dev libopencv-dev
  libceres-dev libsuitesparse-dev libgoogle-glog-dev libopengv-dev libyaml-cpp-dev libcli11-dev
  libspdlog-dev nlohmann-json3-dev libcereal-dev)
if [ "${1:-}" = "--print-packages" ]; then echo "${ARM64_PACKAGES[*]}"; exit 0; fi
SYSROOT="${1:?usage: make-arm64-sysroot.sh SYSROOT | --print-packages}"
MIRROR="${CCM_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
SECURITY_MIRROR="${CCM_DEBIAN_SECURITY_MIRROR:-http://deb.debian.org/debian-security}"
say() { echo "[sysroot] $*"; }
die() { echo "make-arm64-sysroot: ERROR: $*" >&2; exit 1; }

STAMP_TEXT="bookworm arm64: ${ARM64_PACKAGES[*]}"
if [ -f "$SYSROOT/.ccm-sysroot" ] && [ "$(cat "$SYSROOT/.ccm-sysroot")" = "$STAMP_TEXT" ]; then
  say "reusing $SYSROOT ($(du -sh "$SYSROOT" | cut -f1); remove it to rebuild)"
  exit 0
fi
command -v mmdebstrap >/dev/null || die "mmdebstrap missing (apt-get install mmdebstrap)"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || die "mmdebstrap --mode=root needs root or sudo"
  SUDO="sudo"
fi

T="$SYSROOT.partial"
$SUDO rm -rf "$T"
mkdir -p "$(dirname "$SYSROOT")"
say "1. mmdebstrap --variant=extract arm64 bookworm: ${ARM64_PACKAGES[*]} (and their dependencies)"
include="$(IFS=,; echo "${ARM64_PACKAGES[*]}")"
start=$SECONDS
$SUDO mmdebstrap --quiet --mode=root --architectures=arm64 --variant=extract --include="$include" \
  --skip=cleanup/apt/cache bookworm "$T" \
  "deb $MIRROR bookworm main" "deb $MIRROR bookworm-updates main" "deb $SECURITY_MIRROR bookworm-security main" \
  || die "mmdebstrap failed (network? mirror $MIRROR?)"
[ -z "$SUDO" ] || $SUDO chown -R "$(id -u):$(id -g)" "$T"
debs=("$T"/var/cache/apt/archives/*.deb)
[ -e "${debs[0]}" ] || die "mmdebstrap left no .deb files in $T/var/cache/apt/archives"
say "   ${#debs[@]} packages extracted in $((SECONDS - start)) s"

say "2. merged /usr (/bin, /sbin, /lib -> usr/...)"
for d in bin sbin lib; do
  if [ -d "$T/$d" ] && [ ! -L "$T/$d" ]; then
    mkdir -p "$T/usr/$d"
    while IFS= read -r f; do
      [ ! -e "$T/usr/$d/$f" ] || [ -d "$T/usr/$d/$f" ] || die "/$d/$f and /usr/$d/$f both exist"
    done < <(cd "$T/$d" && find . ! -type d)
    cp -a "$T/$d/." "$T/usr/$d/"
    rm -rf "${T:?}/$d"
  fi
  [ -e "$T/$d" ] || ln -s "usr/$d" "$T/$d"
done

say "3. dpkg database from the packages' control data (no maintainer scripts run)"
db="$T/var/lib/dpkg"
mkdir -p "$db/info" "$db/updates"
echo 1 >"$db/info/format"
: >"$db/status"
ctl="$(mktemp -d)"
trap 'rm -rf "$ctl"' EXIT
for deb in "${debs[@]}"; do
  rm -rf "${ctl:?}"/*
  dpkg-deb --control "$deb" "$ctl"
  pkg="$(dpkg-deb --field "$deb" Package)"
  arch="$(dpkg-deb --field "$deb" Architecture)"
  name="$pkg"
  [ "$(dpkg-deb --field "$deb" Multi-Arch)" != same ] || name="$pkg:$arch"
  for f in "$ctl"/*; do
    [ "$(basename "$f")" = control ] || cp "$f" "$db/info/$name.$(basename "$f")"
  done
  dpkg-deb --fsys-tarfile "$deb" | tar -t | sed -e 's|^\./|/|' -e 's|/$||' -e 's|^\.$|/.|' -e 's|^$|/.|' \
    >"$db/info/$name.list"
  { grep '^Package:' "$ctl/control"; echo "Status: install ok installed"
    grep -v '^Package:' "$ctl/control"; echo; } >>"$db/status"
done
n_status="$(grep -c '^Package:' "$db/status")"
[ "$n_status" = "${#debs[@]}" ] || die "dpkg status has $n_status packages, ${#debs[@]} were extracted"
say "   $n_status packages registered"

say "4. alternatives the packages' postinst scripts would register (libblas.so.3, liblapack.so.3 ...)"
# update-alternatives --install lines with literal arguments only (no shell variables), run by
# the host's update-alternatives inside the sysroot (--root): the links it makes are absolute
# and made relative below. Other postinst work (ldconfig, triggers) does not matter to a sysroot.
n=0
for script in "$T"/var/lib/dpkg/info/*.postinst; do
  [ -e "$script" ] || continue
  while IFS= read -r cmd; do
    case "$cmd" in *'$'*|*'"'*|*"'"*|*'|'*|*';'*|*'&'*) continue ;; esac
    read -ra words <<<"$cmd"
    # Some depend on what the rest of their script did (mysql's my.cnf.migrated): said, skipped.
    if update-alternatives --quiet --root "$T" "${words[@]:1}" >/dev/null 2>"$T.alt.err"; then
      n=$((n + 1))
    else
      say "   skipped: ${words[*]:0:3}: $(cat "$T.alt.err")"
    fi
  done < <(sed -e ':a' -e '/\\$/N; s/\\\n//; ta' "$script" | sed -n 's/^[[:space:]]*\(update-alternatives --install .*\)$/\1/p')
done
rm -f "$T.alt.err"
say "   $n alternatives"

say "5. absolute symlinks made relative"
n=0
while IFS= read -r link; do
  target="$(readlink "$link")"
  case "$target" in /proc/*|/dev/*) continue ;; esac
  rel="$(realpath -m -s --relative-to="$(dirname "$link")" "$T$target")"
  ln -sfn "$rel" "$link"
  n=$((n + 1))
done < <(find "$T" -type l -lname '/*')
say "   $n symlinks"

say "6. CMake package files: absolute /usr paths inside the sysroot"
# Debian's Fast DDS configs set _IMPORT_PREFIX "/usr" and name /usr/lib/aarch64-linux-gnu/...
# libraries; Ceres, OpenGV, Imath, glog name /usr/... paths too. With the sysroot they are
# ${CMAKE_SYSROOT}/usr/... (CMAKE_SYSROOT: cmake/toolchain-aarch64-sysroot.cmake); the pattern
# of Debian's multiarch configs (_realOrig "/usr/lib/...") then resolves inside it as well.
n=0
while IFS= read -r f; do
  # shellcheck disable=SC2016  # ${CMAKE_SYSROOT} is for CMake to expand, not the shell
  sed -i -e 's#\([";( ]\)/usr/\(lib\|include\|share\)/#\1${CMAKE_SYSROOT}/usr/\2/#g' \
    -e 's#"/usr"#"${CMAKE_SYSROOT}/usr"#g' "$f"
  n=$((n + 1))
done < <(grep -rlE '["; (]/usr(/(lib|include|share)/|")' --include='*.cmake' "$T/usr/lib" "$T/usr/share" 2>/dev/null)
say "   $n files"

rm -f "${debs[@]}"
[ -e "$T/lib/ld-linux-aarch64.so.1" ] || die "no /lib/ld-linux-aarch64.so.1 in the sysroot"
echo "$STAMP_TEXT" >"$T/.ccm-sysroot"
rm -rf "$SYSROOT"
mv "$T" "$SYSROOT"
say "done: $SYSROOT ($(du -sh "$SYSROOT" | cut -f1), $((SECONDS - start)) s)"
