#!/usr/bin/env python3
"""How often this machine takes a CPU away: one process per core spins reading the monotonic
clock and counts the pauses between two readings. On a quiet machine the readings are a
fraction of a microsecond apart; a pause is time the core ran something else (the kernel, or
on a virtual machine the host). Run it before latency figures (the daemon's p99,
docs/performance.md): a frame whose work meets a pause is late by it. "at once" counts the
pauses over 0.5 ms that overlap one on another core: pauses of the whole machine, which no
second core could work through.

    python3 scripts/host-pauses.py [--seconds 20]
"""
import argparse
import multiprocessing
import os
import time

LIMITS_MS = (0.5, 2.0, 5.0)


def spin(core, seconds, out):
    os.sched_setaffinity(0, {core})
    counts = [0] * len(LIMITS_MS)
    longest = 0
    spans = []  # (start, end) of each pause over the first limit
    now = time.monotonic_ns
    end = now() + int(seconds * 1e9)
    last = now()
    while last < end:
        t = now()
        pause = t - last
        if pause > LIMITS_MS[0] * 1e6:
            spans.append((last, t))
        last = t
        for i, limit in enumerate(LIMITS_MS):
            if pause <= limit * 1e6:
                break
            counts[i] += 1
        longest = max(longest, pause)
    out.put((core, counts, longest / 1e6, spans))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20)
    args = parser.parse_args()
    cores = sorted(os.sched_getaffinity(0))
    out = multiprocessing.Queue()
    spinners = [multiprocessing.Process(target=spin, args=(c, args.seconds, out)) for c in cores]
    for p in spinners:
        p.start()
    results = sorted(out.get() for _ in spinners)
    for p in spinners:
        p.join()
    print(f"{time.strftime('%H:%M:%S')}, {args.seconds:g} s on each of {len(cores)} cores")
    for core, counts, longest, spans in results:
        others = [s for c, _, _, other in results if c != core for s in other]
        at_once = sum(any(start < e and s < end for s, e in others) for start, end in spans)
        over = ", ".join(f"> {limit:g} ms: {n}" for limit, n in zip(LIMITS_MS, counts))
        print(f"core {core}: pauses {over}; longest {longest:.2f} ms; at once with another core: {at_once}")


if __name__ == "__main__":
    main()
