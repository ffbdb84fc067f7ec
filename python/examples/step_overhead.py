"""Per-batch cost of the gymnasium facade's sync ``step()``, before/after side by side.

Times, in interleaved rounds on the same machine state (64 envs, 2 workers, paper config,
random actions):

* ``step``: ``RogueVectorEnv.step`` (one native call decodes the results into reused columns);
* ``native``: the bare native ``Pool.step`` call from Python (columns decoded, nothing else: the floor
  of any facade);
* with ``--pool-bench PATH``: ``rogue-gym pool-bench --mode shared`` (raw single-process
  engine loop and the Rust pool alone) in the same rounds.

    python python/examples/step_overhead.py --rounds 5 --pool-bench target/release/rogue-gym

To compare two builds, run it under each in turn (``PYTHONPATH=<other checkout>/python``, with
that checkout's extension built), several times, and compare the medians of ``step``.
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import time
from typing import Any

import numpy as np

import rogue_gym


def time_loop(env: Any, step: Any, actions: np.ndarray, batches: int) -> float:
    for i in range(20):
        step(actions[i % len(actions)])
    t0 = time.perf_counter()
    for i in range(batches):
        _, _, term, trunc, infos = step(actions[i % len(actions)])
        done = term | trunc
        if done.any():
            infos["episode_return"][done].tolist()
    return batches * env.num_envs / (time.perf_counter() - t0)


def pool_bench(path: str, envs: int, workers: int, steps: int) -> tuple[float, float]:
    out = subprocess.run(
        [
            path,
            "pool-bench",
            "--envs",
            str(envs),
            "--workers",
            str(workers),
            "--mode",
            "shared",
            "--steps",
            str(steps),
        ],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    nums = [float(x.replace(",", "")) for x in re.findall(r"([\d,.]+) env-steps/s", out)]
    if len(nums) < 2:
        raise RuntimeError(f"cannot parse pool-bench output:\n{out}")
    return nums[0], nums[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--num-envs", type=int, default=64)
    ap.add_argument("--num-workers", type=int, default=2)
    ap.add_argument("--batches", type=int, default=3000, help="batches per timed chunk")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--pool-bench", default=None, help="path of the rogue-gym binary")
    args = ap.parse_args()
    env = rogue_gym.make_vec(args.num_envs, config="paper", num_workers=args.num_workers, seed=0)
    actions = np.random.default_rng(0).integers(0, 11, size=(256, args.num_envs))
    env.reset()
    res: dict[str, list[float]] = {"step": [], "native": [], "raw": [], "pool": []}
    core = env._core
    # The bare native call (a build that keeps its pool elsewhere is timed by `step` only).
    pool = getattr(core, "pool", None)

    def native(a: np.ndarray) -> tuple[Any, ...]:
        pool.step(a)  # type: ignore[union-attr]
        return None, None, np.zeros(1, bool), np.zeros(1, bool), {}

    try:
        for r in range(args.rounds):
            res["step"].append(time_loop(env, env.step, actions, args.batches))
            line = f"round {r}: step {res['step'][-1]:,.0f}"
            if pool is not None:
                res["native"].append(time_loop(env, native, actions, args.batches))
                line += f"  native {res['native'][-1]:,.0f}"
            if args.pool_bench:
                raw, rust = pool_bench(
                    args.pool_bench, args.num_envs, args.num_workers, args.batches
                )
                res["raw"].append(raw)
                res["pool"].append(rust)
                line += f"  raw loop {raw:,.0f}  rust pool (shared) {rust:,.0f}"
            print(line + " env-steps/s", flush=True)
    finally:
        env.close()
    med = {k: statistics.median(v) for k, v in res.items() if v}
    print("medians: " + ", ".join(f"{k} {v:,.0f}" for k, v in med.items()))
    if "raw" in med:
        floor = f" (native call alone {med['native'] / med['raw']:.0%})" if "native" in med else ""
        print(
            f"python step / raw loop: {med['step'] / med['raw']:.0%}{floor}; "
            f"rust pool / raw: {med['pool'] / med['raw']:.0%}"
        )


if __name__ == "__main__":
    main()
