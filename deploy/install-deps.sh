#!/usr/bin/env bash
# Installs the Debian 12 packages ccm-slam-dds needs (only those missing). Uses sudo when
# not root. Nothing is downloaded from anywhere but the Debian archive.
# --demo: only what building and running the binaries needs (deploy/run-demo.sh), not what
# only the tests need (GoogleTest, Chromium for the map view page test, the packaging tools).
set -euo pipefail
demo_only=0
[ "${1:-}" = "--demo" ] && demo_only=1

PACKAGES=(
  cmake g++ make ccache pkg-config
  libfastrtps-dev libfastcdr-dev fastddsgen fastdds-tools
  libeigen3-dev libopencv-dev libceres-dev libsuitesparse-dev libopengv-dev
  libyaml-cpp-dev libcli11-dev libspdlog-dev nlohmann-json3-dev libcereal-dev
  python3 openssl
  # Live map view (docs/map-view.md): HTTP server, three.js for the page.
  libcpp-httplib-dev libjs-three
)
TEST_PACKAGES=(
  libgtest-dev libgmock-dev
  dpkg-dev file  # Debian packages (cpack DEB: dpkg-shlibdeps, file); ctest packaging_debian
  chromium       # the map view page in a headless browser (ctest MapViewPage.*)
  python3-prometheus-client  # parses /metrics in a test (Prometheus' own text-format parser)
  gstreamer1.0-plugins-base  # videotestsrc: a GStreamer pipeline as a live camera (ctest LiveCameraSource.*)
)
[ "$demo_only" = 1 ] || PACKAGES+=("${TEST_PACKAGES[@]}")

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "[deps] all ${#PACKAGES[@]} packages present"
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "[deps] need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  SUDO="sudo"
fi
echo "[deps] installing: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
