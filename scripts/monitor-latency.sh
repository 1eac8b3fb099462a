#!/usr/bin/env bash
# What the monitor page costs the frame path (docs/monitor.md): capture->output latency of
# `lipdrive run --config <config/lipdrive.toml> --frames N --stats` (the simulated camera at
# 60 fps), in rounds of three runs:
#   off     [monitor] enabled = false
#   idle    the monitor on, nobody looking
#   loaded  the page open in a headless Chromium and 50 clients polling /api/state 5 times a
#           second each (build/tests/monitor_load)
# The clients run on this machine, at `nice CLIENT_NICE` (default 0; 19 stands in for a browser
# on the operator's own computer, which is where it is in a studio).
# REALTIME_PRIORITY (default 0, the reference file's normal scheduler) > 0 runs the daemon as a
# show does, its frame path under SCHED_FIFO at that priority ([scheduling] realtime_priority,
# docs/packaging.md); the run says so when the system refused it.
# One line per run: the load average before it, capture->output median and p99 (and
# capture->processed's), fps, the daemon's CPU time, and for the loaded runs what the clients
# got; then the daemon's CPU time per thread (by thread name).
#
# usage: scripts/monitor-latency.sh [FRAMES=3600] [ROUNDS=3] [CLIENT_NICE=0] [REALTIME_PRIORITY=0]
set -euo pipefail
cd "$(dirname "$0")/.."
frames=${1:-3600}
rounds=${2:-3}
client_nice=${3:-0}
realtime_priority=${4:-0}
build=build
for tool in "$build/lipdrive" "$build/tests/monitor_load" /usr/bin/chromium; do
  [ -x "$tool" ] || { echo "monitor-latency: $tool is missing (build, scripts/install-deps.sh)" >&2; exit 1; }
done

work=$(mktemp -d)
browser=""
load=""
cleanup() {
  [ -n "$browser" ] && kill "$browser" 2>/dev/null && wait "$browser" 2>/dev/null
  [ -n "$load" ] && kill "$load" 2>/dev/null && wait "$load" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT

# A loopback TCP port nothing listens on.
free_port() {
  local port
  while :; do
    port=$((20000 + RANDOM % 40000))
    (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null || { echo "$port"; return; }
  done
}

# The reference configuration with free ports; $1: the monitor on (true) or off (false).
write_config() {
  sed -e "s/^port = 1502$/port = $(free_port)/" \
      -e "s/^port = 8480$/port = $monitor_port/" \
      -e "/^\[monitor\]$/,/^\[/ s/^enabled = true$/enabled = $1/" \
      -e "/^\[scheduling\]$/,/^\[/ s/^realtime_priority = 0$/realtime_priority = $realtime_priority/" \
      config/lipdrive.toml > "$work/lipdrive.toml"
  grep -q "^realtime_priority = $realtime_priority$" "$work/lipdrive.toml" ||
    { echo "monitor-latency: no [scheduling] realtime_priority = 0 in config/lipdrive.toml to change" >&2; exit 1; }
}

# CPU seconds the daemon (all its threads) has used so far, then one line per thread: its id,
# name and CPU seconds.
cpu_seconds() {
  local pid=$1 fields task
  fields=$(cut -d')' -f2 "/proc/$pid/stat" 2>/dev/null) || return 1  # gone already
  set -- $fields  # from the state on: utime is the 12th field, stime the 13th
  echo "daemon CPU $(awk "BEGIN {printf \"%.2f\", (${12} + ${13}) / $(getconf CLK_TCK)}") s"
  for task in /proc/"$pid"/task/*; do
    fields=$(cat "$task/stat" 2>/dev/null) || continue
    echo "${task##*/} ${fields#*(}"
  done | awk -v tick="$(getconf CLK_TCK)" '{
      name = substr($0, index($0, " ") + 1, index($0, ")") - index($0, " ") - 1)
      split(substr($0, index($0, ")") + 2), f, " ")  # f[1] the state: utime is f[12], stime f[13]
      printf "%s %s %.2f\n", $1, name, (f[12] + f[13]) / tick
    }'
}

# The threads' CPU seconds from every sample of cpu_seconds in $1 (a thread's last sample),
# summed by name, most first.
threads_cpu() {
  grep -v "^daemon CPU" "$1" | awk '{ cpu[$1] = $3; name[$1] = $2 } END {
      for (t in cpu) { total[name[t]] += cpu[t]; n[name[t]]++ }
      for (k in total) printf "%s %.2f s%s\n", k, total[k], (n[k] > 1 ? " (" n[k] " threads)" : "")
    }' | sort -k2,2nr | awk 'NR > 1 { printf ", " } { printf "%s", $0 } END { print "" }'
}

run() {  # $1: off | idle | loaded
  monitor_port=$(free_port)
  write_config "$([ "$1" = off ] && echo false || echo true)"
  local before
  before=$(cut -d' ' -f1-3 /proc/loadavg)
  "$build/lipdrive" run --config "$work/lipdrive.toml" --frames "$frames" --stats 2> "$work/daemon.log" &
  local daemon=$!
  local clients=""
  if [ "$1" = loaded ]; then
    for _ in $(seq 600); do grep -q "monitor: http://" "$work/daemon.log" && break; sleep 0.1; done
    nice -n "$client_nice" /usr/bin/chromium --headless=new --no-sandbox --disable-gpu --disable-quic \
      --no-first-run --disable-background-networking --disable-component-update --disable-sync \
      --disable-dev-shm-usage --window-size=1280,1000 --user-data-dir="$work/profile" \
      "http://127.0.0.1:$monitor_port/" > "$work/chromium.log" 2>&1 &
    browser=$!
    # Until the daemon has processed its frames (below), however long that takes.
    nice -n "$client_nice" "$build/tests/monitor_load" --port "$monitor_port" --clients 50 --hz 5 \
      --seconds 86400 > "$work/load.log" 2>&1 &
    load=$!
  fi
  # The daemon's CPU time, sampled every second while it runs (the last sample is reported).
  (while kill -0 "$daemon" 2>/dev/null; do cpu_seconds "$daemon" >> "$work/cpu.txt"; sleep 1; done) &
  local sampler=$!
  wait "$daemon"
  wait "$sampler" || true
  if [ "$1" = loaded ]; then
    wait "$load" || true  # its clients stop when the daemon's monitor is gone
    kill "$browser" 2>/dev/null || true
    wait "$browser" 2>/dev/null || true
    browser=""
    load=""
    clients=" | $(cat "$work/load.log")"
    rm -rf "$work/profile"
  fi
  local latency processed fps scheduler=""
  latency=$(grep "capture->output latency" "$work/daemon.log" | sed 's/.*latency: //')
  processed=$(grep "capture->processed latency" "$work/daemon.log" | sed 's/.*latency: //')
  fps=$(grep "^fps:" "$work/daemon.log")
  if [ "$realtime_priority" -gt 0 ] && ! grep -q "frame path runs under SCHED_FIFO" "$work/daemon.log"; then
    scheduler=" | SCHED_FIFO refused: $(grep "frame path runs under the normal scheduler" "$work/daemon.log")"
  fi
  echo "$1 | load $before | $latency (capture->processed $processed) | $fps | $(grep "^daemon CPU" "$work/cpu.txt" | tail -1)$clients$scheduler"
  echo "  threads: $(threads_cpu "$work/cpu.txt")"
  rm -f "$work/cpu.txt"
}

echo "monitor-latency: $frames frames a run, $rounds rounds, clients at nice $client_nice," \
  "frame path $([ "$realtime_priority" -gt 0 ] && echo "under SCHED_FIFO at $realtime_priority" || echo "at normal priority"), $(nproc) cores"
for _ in $(seq "$rounds"); do
  run off
  run idle
  run loaded
done
