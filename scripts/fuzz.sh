#!/usr/bin/env bash
# libFuzzer campaigns on the parsers of outside input (tests/fuzz/):
#   ./scripts/fuzz.sh [TARGET|all] [SECONDS]     default: all, 60 s each, one after the other
#   ./scripts/fuzz.sh smoke [TARGET|all]         CI's run: 100,000 inputs per target from its
#                                                seeds alone, libFuzzer's random seed fixed
# Builds the targets in the ASan lane's build-asan/ (clang, ASan + UBSan + coverage, see
# scripts/sanitize.sh), then runs each from its seed corpus (tests/fuzz/TARGET/) plus what
# earlier runs found (build-asan/fuzz-corpus/TARGET/). A crash, a sanitizer report, a
# timeout (10 s per input) or an input that needs more than 2 GiB is written to
# build-asan/fuzz-findings/TARGET/ and fails the run; libFuzzer's final statistics go to
# build-asan/fuzz-logs/TARGET.log, and one summary line per target to stdout.
# A campaign is a random search: what it finds depends on how long it ran and on the inputs
# earlier runs kept. The smoke run repeats its search on the same code (a count of inputs
# instead of a time, a fixed random seed, nothing kept from earlier runs; only a target whose
# own behaviour varies, such as the configuration's checks of files on disk, strays a little),
# so it fails CI on what a change brings into its reach rather than on a lucky draw; 120 s per
# target at most (a slower machine then stops it early, and says so).
set -euo pipefail
cd "$(dirname "$0")/.."

smoke=0
if [ "${1:-}" = smoke ]; then
  smoke=1
  shift
fi
which=${1:-all}
seconds=${2:-60}
[ $smoke -eq 0 ] || seconds=120

./scripts/sanitize.sh build asan fuzz_targets

# The targets: every lipdrive_fuzz_target() line of tests/fuzz/CMakeLists.txt.
mapfile -t all < <(sed -n 's/^lipdrive_fuzz_target(\([a-z0-9_]*\).*/\1/p' tests/fuzz/CMakeLists.txt)
if [ "$which" = all ]; then targets=("${all[@]}"); else targets=("$which"); fi

export ASAN_OPTIONS="detect_leaks=1:allocator_may_return_null=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
failed=0
for target in "${targets[@]}"; do
  binary=build-asan/fuzz/fuzz_$target
  [ -x "$binary" ] || { echo "fuzz: no target $target (targets: ${all[*]})" >&2; exit 2; }
  corpus=build-asan/fuzz-corpus/$target findings=build-asan/fuzz-findings/$target
  log=build-asan/fuzz-logs/$target.log
  search=()
  if [ $smoke -eq 1 ]; then
    corpus=build-asan/fuzz-smoke-corpus/$target
    rm -rf "$corpus"
    search=(-runs=100000 -seed=1)
  fi
  mkdir -p "$corpus" "$findings" build-asan/fuzz-logs
  # Inputs up to 64 KiB, or as long as the largest seed (a compact predictor is 160 KiB): a
  # seed longer than -max_len would be cut, and never pass its file's checks.
  max_len=$(find "tests/fuzz/$target" -type f -printf '%s\n' | sort -n | tail -1)
  max_len=$((${max_len:-0} > 65536 ? max_len : 65536))
  status=0 start=$SECONDS
  "$binary" "$corpus" "tests/fuzz/$target" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
    -max_len="$max_len" -print_final_stats=1 -artifact_prefix="$findings/" "${search[@]}" >"$log" 2>&1 || status=$?
  # A target that fails before libFuzzer prints any statistics has none (and the run goes on).
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | cut -d' ' -f2 || true)
  ft=$(grep -o 'ft: [0-9]*' "$log" | tail -1 | cut -d' ' -f2 || true)
  limit=""
  [ $smoke -eq 1 ] && [ "${execs:-0}" -lt 100000 ] && [ $status -eq 0 ] && limit=" (stopped at ${seconds} s)"
  echo "fuzz_$target: $((SECONDS - start)) s, ${execs:-?} executions$limit, cov ${cov:-?}, ft ${ft:-?}, exit $status"
  if [ "$status" -ne 0 ]; then
    failed=1
    echo "fuzz_$target: FINDING, see $log and $findings/:" >&2
    grep -E 'ERROR|SUMMARY|==[0-9]+==|Test unit written' "$log" | head -20 >&2 || true
  fi
done
exit $failed
