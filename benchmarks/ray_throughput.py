#!/usr/bin/env python3
"""Steps/s of Rogue-Gym through Ray actors (``rogue_gym.ray.RayVectorEnv``) against one local
pool, on a local Ray cluster.

Cells: ``local`` (``rogue_gym.make_vec`` in this process), then ``RayVectorEnv`` with 1 and 2
actors (``ray-1``, ``ray-2``: sync ``step``; ``ray-2-async``: ``send``/``recv``, each actor's
block answered as soon as it arrives, so one actor steps while the driver handles the other);
the same total of pool workers in every cell (``--workers``, split among the actors),
``symbol_index`` observations, random actions drawn in advance. Each cell runs
``--reps`` windows of ``--seconds`` after a warm-up; the median is reported. On the 2-core VM
there is nothing to gain from a second actor: this records what crossing Ray costs.

Needs the Ray environment (``bash scripts/setup-ray.sh``)::

    .venv-ray/bin/python benchmarks/ray_throughput.py            # ~3 min
    .venv-ray/bin/python benchmarks/ray_throughput.py --num-envs 16 64 256

Writes ``ray_throughput.md`` and ``ray_throughput.json`` under ``--out`` (default
``benchmarks/results``).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path
from typing import Any

from common import write_results

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np


def build(kind: str, n: int, workers: int) -> Any:
    import rogue_gym

    pool = {"obs": "symbol_index", "seed": 0}
    if kind == "local":
        return rogue_gym.make_vec(n, num_workers=workers, **pool)
    from rogue_gym.ray import RayVectorEnv

    actors = int(kind.split("-")[1])
    per_actor = max(1, workers // actors)
    return RayVectorEnv("RogueGym-v0", n, num_actors=actors, num_workers=per_actor, **pool)


def measure_async(envs: Any, n: int, seconds: float, warmup: int) -> float:
    acts = np.random.default_rng(0).integers(0, 11, n)
    envs.reset(seed=0)
    envs.send(acts)
    steps, start = 0, None
    for i in range(10**9):
        if i == warmup:
            steps, start = 0, time.perf_counter()
        *_, infos = envs.recv()
        ids = infos["env_id"]
        envs.send(acts[: len(ids)])
        steps += len(ids)
        if start is not None and time.perf_counter() - start >= seconds:
            break
    while envs.in_flight:  # collect what is in flight before the next window
        envs.recv()
    assert start is not None
    return steps / (time.perf_counter() - start)


def measure(envs: Any, n: int, seconds: float, warmup: int, is_async: bool) -> float:
    if is_async:
        return measure_async(envs, n, seconds, warmup)
    rng = np.random.default_rng(0)
    acts = [rng.integers(0, 11, n) for _ in range(64)]
    envs.reset(seed=0)
    for i in range(warmup):
        envs.step(acts[i % 64])
    i, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds or i < 3:
        envs.step(acts[i % 64])
        i += 1
    return i * n / (time.perf_counter() - start)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--num-envs", nargs="+", type=int, default=[64])
    p.add_argument("--workers", type=int, default=2, help="pool workers in all, every cell")
    p.add_argument("--kinds", nargs="+", default=["local", "ray-1", "ray-2", "ray-2-async"])
    p.add_argument("--reps", type=int, default=5)
    p.add_argument("--seconds", type=float, default=3.0)
    p.add_argument("--warmup", type=int, default=20)
    p.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = p.parse_args()

    import ray

    ray.init(num_cpus=os.cpu_count(), include_dashboard=False, log_to_driver=False)
    results: dict[str, list[float]] = {}
    try:
        for n in args.num_envs:
            for kind in args.kinds:
                envs = build(kind, n, args.workers)
                try:
                    runs = [
                        measure(envs, n, args.seconds, args.warmup, kind.endswith("async"))
                        for _ in range(args.reps)
                    ]
                finally:
                    envs.close()
                results[f"{kind}/{n}"] = runs
                print(
                    f"{kind:6s} n={n:<4d} median {statistics.median(runs):>10,.0f} steps/s "
                    f"(min {min(runs):,.0f}, max {max(runs):,.0f})",
                    flush=True,
                )
    finally:
        ray.shutdown()

    lines = [
        "# Rogue-Gym through Ray actors: steps/s",
        "",
        f"Machine: {platform.machine()}, {os.cpu_count()} CPUs, Python "
        f"{platform.python_version()}, Ray {ray.__version__}. {args.workers} pool workers in "
        f"all per cell; median of {args.reps} windows of {args.seconds:.0f} s; symbol_index "
        "observations.",
        "",
        "| num_envs | backend | steps/s (median) | min-max | vs local pool |",
        "|---|---|---|---|---|",
    ]
    for n in args.num_envs:
        local = results.get(f"local/{n}")
        for kind in args.kinds:
            runs = results[f"{kind}/{n}"]
            med = statistics.median(runs)
            ratio = f"{med / statistics.median(local):.2f}x" if local else ""
            lines.append(
                f"| {n} | {kind} | {med:,.0f} | {min(runs):,.0f}-{max(runs):,.0f} | {ratio} |"
            )
    data = {"args": vars(args), "runs": results}
    write_results(Path(args.out), "ray_throughput", "\n".join(lines), data)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
