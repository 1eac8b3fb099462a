#!/usr/bin/env bash
# Installs every Debian 12 package lipdrive needs to build, run and test; with packages as
# arguments, those instead (the host tools of scripts/cross-arm64.sh, the clang of
# scripts/sanitize.sh). `--libraries` prints the -dev libraries the build compiles and links
# against, one a line, and installs nothing (scripts/cross-arm64.sh unpacks their arm64 builds).
# Idempotent: when everything is present it does nothing and prints nothing.
set -euo pipefail

# dlib's CMake package links BLAS and LAPACK through their -dev packages' libraries, which
# libdlib-dev does not pull in; the monitor's test links OpenSSL.
libraries=(
  libeigen3-dev libopencv-dev libdlib-dev libblas-dev liblapack-dev
  libmodbus-dev libgpiod-dev libcamera-dev libsystemd-dev
  libcli11-dev libspdlog-dev libfmt-dev libtomlplusplus-dev nlohmann-json3-dev
  libtinyobjloader-dev libcpp-httplib-dev zlib1g-dev
  libgtest-dev libgmock-dev libbenchmark-dev libssl-dev
  libola-dev liblo-dev libltc-dev
  libasound2-dev libaubio-dev libavformat-dev libavcodec-dev libswresample-dev libswscale-dev libavutil-dev
)
# What the build, the daemon and the tests run or read besides.
tools=(
  build-essential cmake pkg-config git ccache libdlib-data opencv-data
  socat ffmpeg systemd clang-format ola liblo-tools
  lintian chromium chromium-driver
)

if [ "${1:-}" = "--libraries" ]; then
  printf '%s\n' "${libraries[@]}"
  exit 0
fi
packages=("$@")
[ ${#packages[@]} -eq 0 ] && packages=("${libraries[@]}" "${tools[@]}")

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0

SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
echo "install-deps: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
