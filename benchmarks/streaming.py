"""Streaming stores against plain stores: the native game's sync ``step()`` with the workers
writing the observation rows past the cache (``streaming_stores=True``) or through it
(``False``), for several batch sizes and worker counts: where the default (``None``: stream
when the slots' observations take more than a third of the last-level cache) should draw its
line.

A batch whose slots' observations fit the cache is cheaper written plainly (the lines are
still cached from the slot's last use); a larger one costs a read and a write of memory per
line with plain stores, and only a write with streaming ones, which also leave the caller's
cache alone. The cells run in turn, one pool at a time (plain, streamed, then streamed, plain,
...), ``--reps`` pairs; the table gives the median wall time per call of each, the worker's
env time per call, the caller's own time (wall minus env time, one worker's view) and the
median of the streamed/plain ratios of the pairs.

    python benchmarks/streaming.py --reps 5        # 1 x 384 ... 1 x 4096, 2 x 256 ... 2 x 2048
    python benchmarks/streaming.py --cells 1x4096 --reps 3

Writes ``streaming.json`` and ``streaming.md`` under ``--out`` (default
``benchmarks/results/streaming``).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
from pathlib import Path
from typing import Optional

import numpy as np
import rogue_gym

from common import timed_steps, write_results

DEFAULT_CELLS = (
    "1x384",
    "1x512",
    "1x768",
    "1x1024",
    "1x2048",
    "1x4096",
    "2x256",
    "2x512",
    "2x2048",
)


def run(workers: int, num_envs: int, streaming: Optional[bool], seconds: float) -> tuple:
    """``(wall, env, own)`` seconds per sync step of one fresh pool (``env``: the slowest
    worker's env time)."""
    vec = rogue_gym.make_vec(
        "RogueGym-v0", num_envs=num_envs, num_workers=workers, streaming_stores=streaming
    )
    try:
        rng = np.random.default_rng(0)
        acts = [rng.integers(0, vec.single_action_space.n, num_envs) for _ in range(8)]
        vec.reset(seed=0)
        for a in acts * 2:
            vec.step(a)
        calls, wall, _ = timed_steps(vec, acts, seconds)
        env = max(w.env_s for w in vec.stats().workers) / calls
        return wall / calls, env, wall / calls - env
    finally:
        vec.close()


def main(argv: Optional[list[str]] = None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument(
        "--cells", nargs="+", default=list(DEFAULT_CELLS), help="WORKERSxENVS (envs in all)"
    )
    p.add_argument("--reps", type=int, default=5, help="pairs per cell")
    p.add_argument("--seconds", type=float, default=0.7, help="per run")
    p.add_argument("--out", default="benchmarks/results/streaming")
    args = p.parse_args(argv)
    cells = [tuple(int(x) for x in c.lower().split("x")) for c in args.cells]
    runs: dict[str, dict[str, list[list[float]]]] = {}
    for workers, n in cells:
        key = f"{workers}x{n}"
        got: dict[str, list[list[float]]] = {"plain": [], "streamed": []}
        for rep in range(args.reps):
            order = (False, True) if rep % 2 == 0 else (True, False)
            for streaming in order:
                got["streamed" if streaming else "plain"].append(
                    list(run(workers, n, streaming, args.seconds))
                )
            a, b = got["plain"][-1], got["streamed"][-1]
            print(
                f"{key} pair {rep + 1}: plain {a[0] * 1e6:.0f} us, streamed {b[0] * 1e6:.0f} us"
                f" a call ({b[0] / a[0]:.2f}x)",
                flush=True,
            )
        runs[key] = got
    lines = [
        f"# Streaming stores against plain stores, native game, sync step() ({platform.node()}, "
        f"{len(os.sched_getaffinity(0))} cores, {args.seconds:g} s a run, {args.reps} pairs, "
        "medians)",
        "",
        "| workers x envs | slots' obs (MB) | plain: wall (us) | streamed: wall (us) "
        "| streamed/plain wall | plain: env (us) | streamed: env (us) | plain: own (us) "
        "| streamed: own (us) |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    obs_bytes = 17 * 16 * 32  # the paper config's observation
    for key, got in runs.items():
        workers, n = (int(x) for x in key.split("x"))
        med = {k: [statistics.median(r[i] for r in v) for i in range(3)] for k, v in got.items()}
        ratio = statistics.median(b[0] / a[0] for a, b in zip(got["plain"], got["streamed"]))
        slots_mb = 2 * n * obs_bytes / 2**20
        lines.append(
            f"| {key} | {slots_mb:.1f} | {med['plain'][0] * 1e6:.0f} "
            f"| {med['streamed'][0] * 1e6:.0f} | {ratio:.2f}x | {med['plain'][1] * 1e6:.0f} "
            f"| {med['streamed'][1] * 1e6:.0f} | {med['plain'][2] * 1e6:.1f} "
            f"| {med['streamed'][2] * 1e6:.1f} |"
        )
    text = "\n".join(lines)
    print(text)
    write_results(Path(args.out), "streaming", text, {"seconds": args.seconds, "runs": runs})


if __name__ == "__main__":
    main()
