"""Double buffering with a policy as slow as the envs: the async API's two halves against sync
``step()`` on the same envs.

``sync``: ``step(policy(obs))`` on all ``N`` envs; the workers wait while the policy runs and
the policy waits while the workers step. ``halves``: ``batch_size = N / 2``; the policy runs on
one half (``recv``, ``policy``, ``send``) while the workers step the other, so on two cores the
ideal is 2x. ``halves, rows copied`` is the same loop with each ``recv``'s rows copied out of
their slot rather than handed over as views (``async_views(False)``). The policy is a busy loop as long as the workers' own env time for its rows
(measured from ``stats()`` in a calibration run), so "as slow as the envs". Workloads: the
native game at 1,024 envs and hosted CartPole at 16 envs, with 1 and 2 workers. Cells run in
turn, ``--reps`` times; the table shows the median steps/s and the ratio of halves to sync.

    python benchmarks/double_buffer.py --reps 5
    python benchmarks/double_buffer.py --quick        # a smoke run

Writes ``double_buffer.json`` and ``double_buffer.md`` under ``--out`` (default
``benchmarks/results/double_buffer``).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path
from typing import Any, Callable

import gymnasium as gym
import numpy as np
import rogue_gym

from common import write_results

WORKLOADS = {"rogue": 1024, "CartPole-v1": 16}


def make(env: str, n: int, workers: int, batch: int) -> Any:
    if env == "rogue":
        return rogue_gym.make_vec("RogueGym-v0", num_envs=n, num_workers=workers, batch_size=batch)
    return rogue_gym.PoolVectorEnv(
        [lambda: gym.make(env)] * n, num_workers=workers, batch_size=batch
    )


def spin(seconds: float) -> None:
    """The policy: busy for ``seconds`` (a GIL-holding compute stand-in)."""
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        pass


def env_seconds_per_step(env: str, n: int) -> float:
    """The workers' own env time per env step (one worker, sync steps)."""
    vec = make(env, n, 1, n)
    try:
        vec.reset(seed=0)
        acts = np.zeros(n, np.int64)
        for _ in range(20):
            vec.step(acts)
        before = vec.stats()
        for _ in range(100):
            vec.step(acts)
        after = vec.stats()
        secs = sum(w.env_s for w in after.workers) - sum(w.env_s for w in before.workers)
        steps = sum(w.env_steps for w in after.workers) - sum(w.env_steps for w in before.workers)
        return secs / max(steps, 1)
    finally:
        vec.close()


def run_sync(vec: Any, n: int, per_env: float, seconds: float) -> float:
    acts = np.zeros(n, np.int64)
    vec.reset(seed=0)
    steps, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        spin(per_env * n)
        vec.step(acts)
        steps += n
    return steps / (time.perf_counter() - t0)


def run_halves(vec: Any, n: int, per_env: float, seconds: float) -> float:
    half = n // 2
    acts = np.zeros(half, np.int64)
    vec.async_reset(seed=0)
    steps, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        *_, infos = vec.recv()
        spin(per_env * half)
        vec.send(acts, infos["env_id"])
        steps += half
    vec.recv()  # the other half's last batch
    return steps / (time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--quick", action="store_true", help="a smoke run: 1 rep, 0.3 s, 1 worker")
    ap.add_argument(
        "--per-env-us",
        nargs="*",
        default=[],
        metavar="ENV=US",
        help="the policy's time per env row, instead of the calibration run's (e.g. rogue=0.3): "
        "two builds compared in turn then run the same policy",
    )
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/double_buffer"))
    args = ap.parse_args()
    if args.quick:
        args.reps, args.seconds, args.workers = 1, 0.3, [1]

    cells: list[tuple[str, int, str, Callable[[], float]]] = []
    opened: list[Any] = []
    per_env: dict[str, float] = {}
    modes = ("sync", "halves", "halves, rows copied")
    fixed = {k: float(v) / 1e6 for k, v in (a.split("=", 1) for a in args.per_env_us)}
    for env, n in WORKLOADS.items():
        per_env[env] = fixed[env] if env in fixed else env_seconds_per_step(env, n)
        for w in args.workers:
            sync = make(env, n, w, n)
            halves = make(env, n, w, n // 2)
            copied = make(env, n, w, n // 2)
            # The same halves with each recv's rows copied out of their slot, not viewed.
            copied._core.pool.async_views(False)
            opened += [sync, halves, copied]
            for mode, vec, run in zip(
                modes, (sync, halves, copied), (run_sync, run_halves, run_halves)
            ):
                cells.append(
                    (
                        env,
                        w,
                        mode,
                        lambda v=vec, f=run, n=n, p=per_env[env]: f(v, n, p, args.seconds),
                    )
                )
    rates: dict[tuple[str, int, str], list[float]] = {(e, w, m): [] for e, w, m, _ in cells}
    try:
        for rep in range(args.reps):
            for env, w, mode, fn in cells:
                rates[(env, w, mode)].append(fn())
            print(f"round {rep + 1}/{args.reps} done", flush=True)
    finally:
        for v in opened:
            v.close()

    rows = []
    for env, n in WORKLOADS.items():
        for w in args.workers:
            s, h, c = (statistics.median(rates[(env, w, m)]) for m in modes)
            rows.append(
                {
                    "env": env,
                    "envs": n,
                    "workers": w,
                    "policy_us": per_env[env] * n / 2 * 1e6,
                    "sync": s,
                    "halves": h,
                    "ratio": h / s,
                    "copied": c,
                    "copied_ratio": c / s,
                }
            )
    lines = [
        f"# Two halves against sync step(), policy as slow as the envs ({platform.node()}, "
        f"{os.cpu_count()} CPUs, {args.seconds} s a cell, median of {args.reps})",
        "",
        "| env | envs | workers | policy per half, µs | sync, steps/s | halves, steps/s | "
        "ratio | halves, rows copied | ratio |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['env']} | {r['envs']} | {r['workers']} | {r['policy_us']:.0f} | "
            f"{r['sync']:,.0f} | {r['halves']:,.0f} | {r['ratio']:.2f}x | "
            f"{r['copied']:,.0f} | {r['copied_ratio']:.2f}x |"
        )
    table = "\n".join(lines)
    print(table)
    meta = {"args": {**vars(args), "out": str(args.out)}, "rows": rows}
    write_results(args.out, "double_buffer", table, meta)


if __name__ == "__main__":
    main()
