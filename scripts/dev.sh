#!/usr/bin/env bash
# The quick start: installs what is needed, builds, then
#   ./scripts/dev.sh run    runs the daemon on the embedded defaults (simulated camera)
#   ./scripts/dev.sh test   runs the whole test suite
set -euo pipefail
cd "$(dirname "$0")/.."

job=${1:-}
case "$job" in
  run|test) shift ;;
  *) echo "usage: $0 run|test [args...]" >&2; exit 2 ;;
esac

./scripts/install-deps.sh
# ccache (when installed, see CMakeLists.txt) shares results between checkouts of the tree.
export CCACHE_BASEDIR="$PWD"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)"

case "$job" in
  run)
    # The daemon on the embedded defaults: simulated camera replaying the generated
    # talking-face clip, default model; live mouth parameters in the log. Ctrl-C stops it.
    exec ./build/lipdrive run --config config/lipdrive.toml "$@"
    ;;
  test)
    exec ctest --test-dir build --output-on-failure -j"$(nproc)" "$@"
    ;;
esac
