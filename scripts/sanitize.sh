#!/usr/bin/env bash
# The sanitizer lanes, each in its own build directory beside build/, built with clang:
#   ./scripts/sanitize.sh asan [ctest args]   AddressSanitizer + UndefinedBehaviorSanitizer,
#                                             the whole suite (build-asan/; CI's asan lane)
#   ./scripts/sanitize.sh tsan [ctest args]   ThreadSanitizer, the tests whose code runs on
#                                             several threads (build-tsan/)
#   ./scripts/sanitize.sh build asan|tsan [TARGET...]   configure and build only
# Every report stops the program with an error (-fno-sanitize-recover), so a test that hits
# one fails. build-asan also carries libFuzzer's coverage instrumentation: scripts/fuzz.sh
# builds its targets there, on the same objects. Suppressions, each with its reason, are in
# tests/sanitizers/.
set -euo pipefail
cd "$(dirname "$0")/.."

# The threaded tests: the pipeline's threads and hand-offs, every output kind (Modbus server
# and client, serial, GPIO, DMX and OSC senders), the OSC control port, timecode and audio
# capture, the voice room, the monitor page, the daemon run end to end (outputs, show network,
# face faults, the voice taking over), reload and stop, kill -9 and restart, and the soak with
# every camera fault (shortened to LIPDRIVE_SOAK_SECONDS).
threaded=(test_pipeline test_modbus test_serial test_gpio test_osc test_dmx test_timecode test_audio_input
  test_voice_room test_monitor test_daemon_outputs test_daemon_dmx test_daemon_osc test_daemon_timecode
  test_daemon_face_faults test_daemon_voice test_reload test_crash_restart test_soak)
# The tests with real-time bounds (ALSA capture's 25 ms; the pipeline's stop within a second;
# the daemon's reload, kill -9 and restart, outputs, soak, face faults, DMX, OSC, timecode,
# its calibration run on a GRID clip; the Modbus client's 5 ms publish bound; the monitor's
# daemon above 30 frames/s; the take's rows behind a hand while the voice drives): ASan's
# slower code makes them miss their watchdog, rate and row-count checks without any sanitizer
# report (docs/reliability.md): in the asan lane their verdict is their reports alone (run_tests).
realtime=(test_audio_input test_pipeline test_reload test_crash_restart test_daemon_outputs test_soak
  test_daemon_face_faults test_daemon_dmx test_daemon_osc test_daemon_timecode test_calibrate_grid test_modbus
  test_monitor test_daemon_voice)
# What the daemon tests run and read: the binaries, the default models and predictor, the clips.
generated=(lipdrive lipdrive-dev default_models default_predictor fixtures)

build() {
  local lane=$1
  shift
  ./scripts/install-deps.sh
  # clang, its sanitizer and libFuzzer runtimes, llvm-symbolizer for the reports' stacks.
  ./scripts/install-deps.sh clang libclang-rt-14-dev llvm
  export CCACHE_BASEDIR="$PWD"
  local jobs=$(($(nproc) < 2 ? $(nproc) : 2))
  case "$lane" in
    asan) flags=(-DLIPDRIVE_SANITIZE=address,undefined -DLIPDRIVE_FUZZ=ON) ;;
    tsan)
      flags=(-DLIPDRIVE_SANITIZE=thread)
      # The build runs lipdrive-dev to generate the fixtures, under ThreadSanitizer too.
      export TSAN_OPTIONS="suppressions=$suppressions/tsan.supp"
      ;;
    *) echo "usage: $0 build asan|tsan [TARGET...]" >&2; exit 2 ;;
  esac
  CC=clang CXX=clang++ cmake -S . -B "build-$lane" -DCMAKE_BUILD_TYPE=RelWithDebInfo "${flags[@]}" >/dev/null
  cmake --build "build-$lane" -j"$jobs" ${1:+--target "$@"}
}

suppressions="$PWD/tests/sanitizers"
# Every process the tests start (the daemon, the CLI, the generators' runs) writes its reports
# to build-<lane>/sanitizer-reports/ instead of stderr, so a report in a child process fails
# the lane even when its test only looks at the exit code, or kills the child.
# The tests in `judged_by_reports` (the lane sets it) have their reports as their verdict: under
# ThreadSanitizer the daemon runs 5-15 times slower, under ASan less but enough, so real-time bounds
# (a stop within a second, rows per second, the watchdog) fail without a defect; those failures
# are listed, and the Release lane holds the same tests to their bounds. Any other failing
# test fails the lane. tsan: every test it runs; asan: the real-time tests above.
judged_by_reports=()
run_tests() {
  local lane=$1
  shift
  local reports="$PWD/build-$lane/sanitizer-reports"
  rm -rf "$reports"
  mkdir -p "$reports"
  local status=0
  ctest --test-dir "build-$lane" --output-on-failure -j2 --timeout 1500 "$@" || status=$?
  if [ $status -ne 0 ]; then
    # ctest's list of the tests that failed: "NUMBER:NAME" per line (none: ctest itself failed).
    local failed="build-$lane/Testing/Temporary/LastTestsFailed.log" name others=(ctest)
    if [ -f "$failed" ]; then
      others=()
      while IFS=: read -r _ name; do
        [[ " ${judged_by_reports[*]} " == *" ${name%_shared} "* ]] || others+=("$name")
      done <"$failed"
    fi
    if [ ${#others[@]} -eq 0 ]; then
      echo "sanitize: $lane: the tests above failed on the sanitizer's slowdown, not on a report (none is" \
        "listed below unless there is one); the Release lane checks their bounds" >&2
      status=0
    fi
  fi
  if compgen -G "$reports/*" >/dev/null; then
    echo "sanitize: $lane: reports in $reports:" >&2
    for report in "$reports"/*; do
      echo "---- $report" >&2
      head -60 "$report" >&2
    done
    status=1
  fi
  return $status
}

case "${1:-}" in
  build)
    shift
    build "$@"
    ;;
  asan)
    shift
    build asan
    reports="$PWD/build-asan/sanitizer-reports/report"
    export ASAN_OPTIONS="detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1:log_path=$reports"
    export LSAN_OPTIONS="suppressions=$suppressions/lsan.supp:print_suppressions=0"
    export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:suppressions=$suppressions/ubsan.supp:log_path=$reports"
    judged_by_reports=("${realtime[@]}")
    run_tests asan "$@"
    ;;
  tsan)
    shift
    build tsan "${generated[@]}" "${threaded[@]}"
    reports="$PWD/build-tsan/sanitizer-reports/report"
    export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$suppressions/tsan.supp:log_path=$reports"
    # The soak's threads and faults for 20 s instead of a minute (tests/test_soak.cpp).
    export LIPDRIVE_SOAK_SECONDS=20
    filter="^($(IFS='|'; echo "${threaded[*]}"))(_shared)?\$"
    judged_by_reports=("${threaded[@]}")
    run_tests tsan -R "$filter" "$@"
    ;;
  *)
    echo "usage: $0 asan|tsan [ctest args...] | build asan|tsan [TARGET...]" >&2
    exit 2
    ;;
esac
