"""What a wait costs the work after it, with no pool at all: a list index and a 4 KB numpy copy
timed right after each kind of wait (sleeping, spinning on the clock, ``sched_yield``, or
writing 16 MB of one's own memory), against the same done back to back.

On a host that shares its cores' caches with other tenants, a thread's cache goes cold while
it waits, whatever it does meanwhile; the pool's caller waits as long as the workers step, so
its own time per call grows with the wait as well as with the batch (docs/performance.md,
"What a wait costs"; ``scaling.py --model``'s control measures the same with the pool).

    python benchmarks/cache_decay.py            # 5 rounds of 200 waits each: ~1 min

Writes ``cache_decay.json`` and ``cache_decay.md`` under ``--out`` (default
``benchmarks/results/cache_decay``).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from common import spin, write_results

#: Bytes the "own writes" wait writes (a cache line at a time), about half this VM's L3.
OWN_BYTES = 16 << 20


def _yield(seconds: float) -> None:
    t = time.perf_counter()
    while time.perf_counter() - t < seconds:
        os.sched_yield()


def waits() -> dict[str, Callable[[], None]]:
    """Each wait, by the label the table prints."""
    own = np.zeros(OWN_BYTES, np.uint8)

    def write_own() -> None:
        own[::64] += 1

    return {
        "none (back to back)": lambda: None,
        "sleep 0.5 ms": lambda: time.sleep(0.0005),
        "sleep 8 ms": lambda: time.sleep(0.008),
        "spin 8 ms": lambda: spin(0.008),
        "sched_yield 8 ms": lambda: _yield(0.008),
        f"write {OWN_BYTES >> 20} MB of its own": write_own,
    }


def after(wait: Callable[[], None], times: int) -> tuple[float, float]:
    """Median seconds of a list index and of a 4 KB copy, each right after ``wait``."""
    items, page = [1, 2, 3], np.zeros(4096, np.uint8)
    index, copy = [], []
    clock = time.perf_counter_ns
    for _ in range(times):
        wait()
        t0 = clock()
        items[1]  # the operation timed
        t1 = clock()
        page.copy()
        t2 = clock()
        index.append(t1 - t0)
        copy.append(t2 - t1)
    return statistics.median(index) / 1e9, statistics.median(copy) / 1e9


def main(argv: Optional[list[str]] = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--times", type=int, default=200, help="waits per round and kind")
    p.add_argument("--reps", type=int, default=5, help="rounds (kinds interleaved)")
    p.add_argument("--out", default=str(Path(__file__).parent / "results" / "cache_decay"))
    args = p.parse_args(argv)
    kinds = waits()
    runs: dict[str, list[tuple[float, float]]] = {k: [] for k in kinds}
    for rep in range(args.reps):
        for label, wait in kinds.items():
            runs[label].append(after(wait, args.times))
        print(f"round {rep + 1}/{args.reps} done")
    lines = [
        f"# After a wait ({platform.node()}, {os.cpu_count()} CPUs, {args.times} waits x "
        f"{args.reps} rounds; medians of each round, then the median and range of the rounds)",
        "",
        "| wait | list index (us) | 4 KB copy (us) |",
        "|---|---:|---:|",
    ]
    for label, cells in runs.items():
        shown = []
        for i in (0, 1):
            v = [c[i] * 1e6 for c in cells]
            shown.append(f"{statistics.median(v):.2f} ({min(v):.2f}-{max(v):.2f})")
        lines.append(f"| {label} | {shown[0]} | {shown[1]} |")
    text = "\n".join(lines)
    print(text)
    write_results(Path(args.out), "cache_decay", text, {"times": args.times, "runs": runs})


if __name__ == "__main__":
    main()
