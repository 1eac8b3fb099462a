#!/usr/bin/env bash
# Cross build for arm64 (Debian's cross toolchain and arm64 libraries through multiarch), then
# the arm64 unit tests under qemu-user. Not part of CI (.ci/run): it downloads ~100 MB and
# takes the machine's two cores for minutes. Usage: scripts/cross-arm64.sh [build dir]
# (default build-arm64). LIPDRIVE_MARCH (default armv8-a) is the -march of the board.
#
# Only core/ and its unit tests are built (LIPDRIVE_CORE_ONLY): Debian 12 cannot install the arm64
# -dev packages of OpenCV's imgcodecs/videoio (through libgdcm-dev), liblo and OLA beside the
# native ones that the native build needs (docs/packaging.md, "Cross build for arm64").
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build-arm64}
march=${LIPDRIVE_MARCH:-armv8-a}

packages=(
  cmake ccache libeigen3-dev
  crossbuild-essential-arm64 qemu-user-static
  zlib1g-dev:arm64 libgtest-dev:arm64 libgmock-dev:arm64
)
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
t0=$(date +%s)
if ! dpkg --print-foreign-architectures | grep -qx arm64; then
  $SUDO dpkg --add-architecture arm64
fi
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "cross-arm64: installing ${missing[*]}" >&2
  $SUDO apt-get update -qq
  # --no-remove: never trade a native package for an arm64 one.
  $SUDO apt-get install -y -qq --no-install-recommends --no-remove "${missing[@]}" >/dev/null
fi
t1=$(date +%s)

export CCACHE_BASEDIR=$PWD
cmake -S . -B "$build" -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-aarch64.cmake \
  -DCMAKE_BUILD_TYPE=Release -DLIPDRIVE_MARCH="$march" -DLIPDRIVE_CORE_ONLY=ON >/dev/null
t2=$(date +%s)
nice -n 19 cmake --build "$build" -j2
t3=$(date +%s)
# ctest runs each test binary under CMAKE_CROSSCOMPILING_EMULATOR (the toolchain file).
status=0
ctest --test-dir "$build" --output-on-failure || status=$?
t4=$(date +%s)

echo "cross-arm64: packages $((t1 - t0)) s, configure $((t2 - t1)) s, build $((t3 - t2)) s, tests under qemu $((t4 - t3)) s"
for f in "$build"/core/liblipdrive_core.a "$build"/tests/test_*; do
  [ -f "$f" ] || continue
  echo "cross-arm64: $(stat -c %s "$f") bytes $f ($(aarch64-linux-gnu-objdump -f "$f" | grep -m1 -o 'file format .*'))"
done
exit $status
