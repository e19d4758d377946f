#!/usr/bin/env python3
"""SYNC intervals from a `candump -t a` log (kernel receive stamps, microseconds), for bench/sync_jitter.sh.

Prints one line per file: intervals, their mean (ms: a producer that never catches up on a late
SYNC runs slow), p50/p99/p99.9/max of |interval - period| in microseconds, how many intervals were
off by more than 1 ms, and how many were longer than 1.5 periods (a SYNC late by more than half a
period).
  bench/sync_intervals.py --period-us 20000 --label NAME candump.txt
"""
import argparse
import re
import sys

STAMP = re.compile(r"^\s*\((\d+)\.(\d{6})\)\s+\S+\s+080\s+\[0\]")


def quantile(sorted_values, q):
    if not sorted_values:
        return float("nan")
    i = min(len(sorted_values) - 1, max(0, int(round(q * (len(sorted_values) - 1)))))
    return sorted_values[i]


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--period-us", type=int, default=20000)
    p.add_argument("--label", default="")
    p.add_argument("--header", action="store_true")
    p.add_argument("file")
    a = p.parse_args()
    stamps = []
    with open(a.file) as f:
        for line in f:
            m = STAMP.match(line)
            if m:
                stamps.append(int(m.group(1)) * 1_000_000 + int(m.group(2)))
    intervals = [b - s for s, b in zip(stamps, stamps[1:])]
    dev = sorted(abs(i - a.period_us) for i in intervals)
    late = sum(1 for i in intervals if i > 1.5 * a.period_us)
    off = sum(1 for d in dev if d > 1000)
    mean_ms = sum(intervals) / len(intervals) / 1000 if intervals else float("nan")
    if a.header:
        print(f"{'case':<22} {'n':>6} {'mean_ms':>8} {'p50_us':>7} {'p99_us':>7} {'p99.9_us':>8} {'max_us':>7} "
              f"{'>1ms':>5} {'>1.5T':>6}")
    print(f"{a.label:<22} {len(intervals):>6} {mean_ms:>8.3f} {quantile(dev, 0.5):>7} {quantile(dev, 0.99):>7} "
          f"{quantile(dev, 0.999):>8} {max(dev) if dev else float('nan'):>7} {off:>5} {late:>6}")
    return 0 if intervals else 1


if __name__ == "__main__":
    sys.exit(main())
