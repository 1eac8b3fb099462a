#!/usr/bin/env bash
# Installs every Debian 12 package lipdrive needs to build, run and test.
# Idempotent: when everything is present it does nothing and prints nothing.
set -euo pipefail

packages=(
  build-essential cmake pkg-config git ccache
  libeigen3-dev libopencv-dev libdlib-dev libdlib-data
  libmodbus-dev libgpiod-dev libcamera-dev libsystemd-dev
  libcli11-dev libspdlog-dev libfmt-dev libtomlplusplus-dev nlohmann-json3-dev
  libtinyobjloader-dev libcpp-httplib-dev zlib1g-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  socat ffmpeg systemd clang-format
  libola-dev ola liblo-dev liblo-tools libltc-dev
  lintian chromium chromium-driver
  libasound2-dev libaubio-dev libavformat-dev libavcodec-dev libswresample-dev libswscale-dev libavutil-dev
)

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
