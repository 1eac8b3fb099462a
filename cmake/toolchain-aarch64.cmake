# Cross build for arm64 boards with Debian's cross toolchain (crossbuild-essential-arm64) and
# the arm64 libraries installed beside the native ones (multiarch, /usr/lib/aarch64-linux-gnu).
# Used by scripts/cross-arm64.sh; pass -DLIPDRIVE_MARCH=armv8-a (or the board's core), since
# -march=native means nothing to a cross compiler.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
# pkg-config reads the arm64 libraries' .pc files, never the host's.
set(ENV{PKG_CONFIG_LIBDIR} /usr/lib/aarch64-linux-gnu/pkgconfig:/usr/share/pkgconfig)
# Test binaries (ctest) and build-time tools run under qemu-user; the arm64 C library of the
# cross toolchain is its root for the dynamic loader.
find_program(LIPDRIVE_QEMU_AARCH64 qemu-aarch64-static)
if(LIPDRIVE_QEMU_AARCH64)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${LIPDRIVE_QEMU_AARCH64} -L /usr/aarch64-linux-gnu)
endif()
