#!/usr/bin/env bash
# The sanitizer lanes, each in its own build directory beside build/, built with clang:
#   ./scripts/sanitize.sh asan [ctest args]   AddressSanitizer + UndefinedBehaviorSanitizer,
#                                             the whole suite (build-asan/)
#   ./scripts/sanitize.sh tsan [ctest args]   ThreadSanitizer, the tests whose code runs on
#                                             several threads (build-tsan/)
#   ./scripts/sanitize.sh build asan|tsan [TARGET...]   configure and build only
# Every report stops the program with an error (-fno-sanitize-recover), so a test that hits
# one fails. build-asan also carries libFuzzer's coverage instrumentation: scripts/fuzz.sh
# builds its targets there, on the same objects. Suppressions, each with its reason, are in
# tests/sanitizers/.
set -euo pipefail
cd "$(dirname "$0")/.."

# The threaded tests: the pipeline's threads and hand-offs, every output kind, the Modbus
# server and client, serial, reload and stop, kill -9 and restart.
threaded=(test_pipeline test_modbus test_serial test_gpio test_daemon_outputs test_reload test_crash_restart)

build() {
  local lane=$1
  shift
  ./scripts/install-deps.sh
  export CCACHE_BASEDIR="$PWD"
  local jobs=$(($(nproc) < 2 ? $(nproc) : 2))
  case "$lane" in
    asan) flags=(-DLIPDRIVE_SANITIZE=address,undefined -DLIPDRIVE_FUZZ=ON) ;;
    tsan) flags=(-DLIPDRIVE_SANITIZE=thread) ;;
    *) echo "usage: $0 build asan|tsan [TARGET...]" >&2; exit 2 ;;
  esac
  CC=clang CXX=clang++ cmake -S . -B "build-$lane" -DCMAKE_BUILD_TYPE=RelWithDebInfo "${flags[@]}" >/dev/null
  cmake --build "build-$lane" -j"$jobs" ${1:+--target "$@"}
}

suppressions="$PWD/tests/sanitizers"
case "${1:-}" in
  build)
    shift
    build "$@"
    ;;
  asan)
    shift
    build asan
    export ASAN_OPTIONS="detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1"
    export LSAN_OPTIONS="suppressions=$suppressions/lsan.supp:print_suppressions=0"
    export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:suppressions=$suppressions/ubsan.supp"
    exec ctest --test-dir build-asan --output-on-failure -j2 --timeout 1500 "$@"
    ;;
  tsan)
    shift
    build tsan "${threaded[@]}"
    export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$suppressions/tsan.supp"
    filter="^($(IFS='|'; echo "${threaded[*]}"))\$"
    exec ctest --test-dir build-tsan --output-on-failure -j2 --timeout 1500 -R "$filter" "$@"
    ;;
  *)
    echo "usage: $0 asan|tsan [ctest args...] | build asan|tsan [TARGET...]" >&2
    exit 2
    ;;
esac
