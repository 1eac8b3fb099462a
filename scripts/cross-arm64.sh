#!/usr/bin/env bash
# Cross build of the whole product for arm64 boards, then its board-independent tests under
# qemu-user. Not part of CI (.ci/run): it downloads ~330 MB and takes the machine's two cores for
# about half an hour. Usage: scripts/cross-arm64.sh [build dir] (default build-arm64).
# LIPDRIVE_MARCH (default armv8-a) is the -march of the board.
#
# The arm64 libraries come from Debian's own arm64 packages, unpacked into a root of their own
# (<build dir>/sysroot) by apt with a private state (<build dir>/apt): the host's packages, its
# architectures and its native build are not touched. Debian's cross compilers build against
# that root (cmake/toolchain-aarch64.cmake).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build-arm64}
march=${LIPDRIVE_MARCH:-armv8-a}
mkdir -p "$build"
build=$(cd "$build" && pwd)
sysroot=$build/sysroot
state=$build/apt

libdir=/usr/lib/aarch64-linux-gnu  # Debian's arm64 library folder, in the root
# The arm64 root: the -dev libraries the product builds against (scripts/install-deps.sh), and
# the C and C++ runtimes, which the host has through its compiler.
mapfile -t arm64_packages < <(./scripts/install-deps.sh --libraries)
arm64_packages+=(libc6-dev libstdc++-12-dev)
# The tests run under emulation: those that neither time the daemon (their bounds are for the
# native build; emulated, everything is 10-25x slower), nor start `lipdrive` as a program of
# its own (without the kernel's binfmt_misc, an arm64 program cannot start another), nor need
# olad or a browser.
emulated_tests=(
  test_metrics test_mouth_measures test_calibration test_drive_channels test_fit_allocations
  test_fitting test_lip_contact test_face_tracker test_arkit test_voice_model test_model_format
  test_expression_fit test_synthetic_head test_ict_import test_viseme_weights test_filters_indices
  test_side_profile test_talking_face test_simulated_camera test_media_files test_timecode
  test_v4l2_camera test_libcamera_camera test_gpio test_serial test_dmx test_osc test_systemd_unit
)

t0=$(date +%s)
# Host tools: the cross compilers and the emulator.
./scripts/install-deps.sh cmake ccache pkg-config crossbuild-essential-arm64 qemu-user-static

# The root is made again when the package list changes.
want="${arm64_packages[*]}"
if [ "$(cat "$sysroot/.packages" 2>/dev/null)" != "$want" ]; then
  echo "cross-arm64: unpacking the arm64 root in $sysroot" >&2
  rm -rf "$sysroot" "$state"
  mkdir -p "$state/lists/partial" "$state/cache/archives/partial" "$state/preferences.d" "$sysroot"
  : >"$state/status"
  keyring=/usr/share/keyrings/debian-archive-keyring.gpg
  cat >"$state/sources.list" <<EOF
deb [arch=arm64 signed-by=$keyring] http://deb.debian.org/debian bookworm main
deb [arch=arm64 signed-by=$keyring] http://deb.debian.org/debian bookworm-updates main
deb [arch=arm64 signed-by=$keyring] http://deb.debian.org/debian-security bookworm-security main
EOF
  apt=(apt-get -qq
    -o Dir::Etc::SourceList="$state/sources.list" -o Dir::Etc::SourceParts=/dev/null
    -o Dir::Etc::Preferences=/dev/null -o Dir::Etc::PreferencesParts="$state/preferences.d"
    -o Dir::State::Lists="$state/lists" -o Dir::State::Status="$state/status"
    -o Dir::Cache="$state/cache" -o APT::Architecture=arm64 -o APT::Architectures::=arm64
    -o Debug::NoLocking=1)
  "${apt[@]}" update
  "${apt[@]}" install -y --download-only --no-install-recommends "${arm64_packages[@]}" >/dev/null
  for deb in "$state"/cache/archives/*.deb; do dpkg-deb -x "$deb" "$sysroot"; done
  # Debian 12 merges /lib, /bin and /sbin into /usr; some packages still ship files there.
  for d in lib bin sbin; do
    if [ -d "$sysroot/$d" ] && [ ! -L "$sysroot/$d" ]; then
      mkdir -p "$sysroot/usr/$d"
      cp -a "$sysroot/$d/." "$sysroot/usr/$d/"
      rm -rf "${sysroot:?}/$d"
      ln -s "usr/$d" "$sysroot/$d"
    fi
  done
  # Absolute symbolic links (libz.so -> /lib/...) would leave the root: make them relative.
  (cd "$sysroot" && find . -type l -lname '/*' | while read -r link; do
    ln -sfn "$(realpath -m --relative-to="$(dirname "$link")" "./$(readlink "$link")")" "$link"
  done)
  # The BLAS and LAPACK libraries (dlib's) are reached through update-alternatives, which
  # only a package's installation runs: link the reference ones where it would.
  for lib in "$sysroot$libdir"/{blas,lapack}/lib*.so*; do
    ln -sfn "$(basename "$(dirname "$lib")")/$(basename "$lib")" "$sysroot$libdir/$(basename "$lib")"
  done
  # Absolute library paths that a package's CMake files recorded when Debian built it (dlib's:
  # /usr/lib/aarch64-linux-gnu/libpng.so ...) would leave the root too: point them into it.
  { grep -rlE "[\";]$libdir/lib" "$sysroot$libdir/cmake" "$sysroot/usr/lib/cmake" "$sysroot"/usr/share/*/cmake \
    2>/dev/null || true; } | xargs -r sed -i -E "s#([\";])$libdir/lib#\1$sysroot$libdir/lib#g"
  rm -rf "$state/cache/archives"
  echo "$want" >"$sysroot/.packages"
fi
t1=$(date +%s)

export CCACHE_BASEDIR=$PWD
cmake -S . -B "$build" -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-aarch64.cmake -DLIPDRIVE_ARM64_SYSROOT="$sysroot" \
  -DCMAKE_BUILD_TYPE=Release -DLIPDRIVE_MARCH="$march" >/dev/null
t2=$(date +%s)
nice -n 19 cmake --build "$build" -j2
t3=$(date +%s)
# ctest runs each test binary under CMAKE_CROSSCOMPILING_EMULATOR (the toolchain file).
status=0
ctest --test-dir "$build" -j2 --output-on-failure -R "^($(IFS='|'; echo "${emulated_tests[*]}"))\$" || status=$?
t4=$(date +%s)

echo "cross-arm64: root $((t1 - t0)) s, configure $((t2 - t1)) s, build $((t3 - t2)) s, tests under qemu $((t4 - t3)) s"
for f in "$build"/lipdrive "$build"/lipdrive-dev; do
  echo "cross-arm64: $(stat -c %s "$f") bytes $f ($(aarch64-linux-gnu-objdump -f "$f" | grep -m1 -o 'file format .*'))"
done
exit $status
