#!/usr/bin/env bash
# The sanitizer lanes, each in its own build directory beside build/, built with clang:
#   ./scripts/sanitize.sh asan [ctest args]   AddressSanitizer + UndefinedBehaviorSanitizer,
#                                             the whole suite (build-asan/)
#   ./scripts/sanitize.sh tsan [ctest args]   ThreadSanitizer, the tests whose code runs on
#                                             several threads (build-tsan/)
#   ./scripts/sanitize.sh asan-ci [ctest args]   ASan + UBSan on the tests CI runs (.ci/run):
#                                             every test but the long evaluations (build-asan/)
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
# The tests CI runs under ASan + UBSan (asan-ci): every parser of outside input, the drivers,
# the outputs (Modbus, serial, DMX, OSC, GPIO) and the numeric units; none of them has a
# real-time bound that ASan's slower code could miss. Left to the full lane (asan): the
# evaluations that run the landmark predictor and the fit over whole clips (face tracker,
# process, side profile, smoothing, viseme weights, model builder, lip contact eval, eval
# plot, calibrate grid: minutes to tens of minutes each under ASan on two cores), the
# package, and the tests with real-time bounds (ALSA capture's 25 ms; the daemon's reload,
# kill -9 and restart, outputs, pipeline, soak, face faults, DMX, OSC, timecode): on a loaded
# machine ASan makes them miss their watchdog, rate and time checks without any sanitizer
# report (docs/reliability.md).
asan_ci=(test_config test_model_format test_ict_import test_v4l2_camera test_simulated_camera test_talking_face
  test_metrics test_synthetic_head test_mouth_measures test_fitting test_fit_allocations test_filters_indices
  test_drive_channels test_calibration test_lip_contact test_timecode test_osc test_dmx test_serial test_gpio
  test_modbus test_systemd_unit)
# What the daemon tests run and read: the binaries, the default models and predictor, the clips.
generated=(lipdrive lipdrive-dev default_models default_predictor fixtures)

build() {
  local lane=$1
  shift
  ./scripts/install-deps.sh
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
# The tsan lane's verdict is its reports alone: under ThreadSanitizer the daemon runs 5-15
# times slower, so the tests' real-time bounds (a stop within a second, rows per second, the
# watchdog) fail without a race; those failures are listed, and the Release lane holds the
# same tests to their bounds. In the asan lanes a failing test fails the lane.
run_tests() {
  local lane=$1
  shift
  local reports="$PWD/build-$lane/sanitizer-reports"
  rm -rf "$reports"
  mkdir -p "$reports"
  local status=0
  ctest --test-dir "build-$lane" --output-on-failure -j2 --timeout 1500 "$@" || status=$?
  if [ "$lane" = tsan ] && [ $status -ne 0 ]; then
    echo "sanitize: tsan: the tests above failed on ThreadSanitizer's slowdown, not on a report (none is" \
      "listed below unless there is one); the Release lane checks their bounds" >&2
    status=0
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
  asan | asan-ci)
    lane=$1
    shift
    filter=()
    if [ "$lane" = asan-ci ]; then
      build asan "${generated[@]}" "${asan_ci[@]}"
      filter=(-R "^($(IFS='|'; echo "${asan_ci[*]}"))\$")
    else
      build asan
    fi
    reports="$PWD/build-asan/sanitizer-reports/report"
    export ASAN_OPTIONS="detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1:log_path=$reports"
    export LSAN_OPTIONS="suppressions=$suppressions/lsan.supp:print_suppressions=0"
    export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:suppressions=$suppressions/ubsan.supp:log_path=$reports"
    run_tests asan "${filter[@]}" "$@"
    ;;
  tsan)
    shift
    build tsan "${generated[@]}" "${threaded[@]}"
    reports="$PWD/build-tsan/sanitizer-reports/report"
    export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$suppressions/tsan.supp:log_path=$reports"
    # The soak's threads and faults for 20 s instead of a minute (tests/test_soak.cpp).
    export LIPDRIVE_SOAK_SECONDS=20
    filter="^($(IFS='|'; echo "${threaded[*]}"))(_shared)?\$"
    run_tests tsan -R "$filter" "$@"
    ;;
  *)
    echo "usage: $0 asan|asan-ci|tsan [ctest args...] | build asan|tsan [TARGET...]" >&2
    exit 2
    ;;
esac
