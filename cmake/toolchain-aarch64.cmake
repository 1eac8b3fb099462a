# Cross build for arm64 boards: Debian's cross compilers (crossbuild-essential-arm64) against an
# arm64 root of Debian's own packages, LIPDRIVE_ARM64_SYSROOT (scripts/cross-arm64.sh makes it),
# so nothing of the host's native libraries is replaced or seen. Pass -DLIPDRIVE_MARCH=armv8-a
# (or the board's core), since -march=native means nothing to a cross compiler.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
# GCC's note that GCC 10.1 changed how some structures are passed concerns mixing objects of
# older compilers; everything here is built by one.
set(CMAKE_CXX_FLAGS_INIT -Wno-psabi)

if(NOT LIPDRIVE_ARM64_SYSROOT)
  message(FATAL_ERROR "LIPDRIVE_ARM64_SYSROOT: the arm64 root to build against (scripts/cross-arm64.sh)")
endif()
# try_compile projects read this file again: hand them the root too.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES LIPDRIVE_ARM64_SYSROOT)
set(CMAKE_SYSROOT ${LIPDRIVE_ARM64_SYSROOT})
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
# pkg-config reads the root's .pc files and prefixes their paths with it.
set(ENV{PKG_CONFIG_PATH} "")
set(ENV{PKG_CONFIG_LIBDIR} ${CMAKE_SYSROOT}/usr/lib/aarch64-linux-gnu/pkgconfig:${CMAKE_SYSROOT}/usr/share/pkgconfig)
set(ENV{PKG_CONFIG_SYSROOT_DIR} ${CMAKE_SYSROOT})

# The tests (ctest) and the build's own generators (the default models, the predictor file, the
# fixtures) run under qemu-user, with the root as the dynamic loader's.
find_program(LIPDRIVE_QEMU_AARCH64 qemu-aarch64-static REQUIRED)
set(CMAKE_CROSSCOMPILING_EMULATOR ${LIPDRIVE_QEMU_AARCH64} -L ${CMAKE_SYSROOT})
