"""A random agent on the paper's config through the environment pool.

Steps ``--num-envs`` games (default 64) in ``--num-workers`` worker processes with uniformly
random actions and prints the throughput (env steps per second) and the mean episode score
(gold + 50 per new floor, 500-step episodes). ``--compare`` also times gymnasium's
``AsyncVectorEnv(shared_memory=True)`` hosting the same engine (one process per env).

    python python/examples/random_agent.py --steps 200000
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import rogue_gym


def run_pool(args: argparse.Namespace) -> float:
    envs = rogue_gym.make_vec(
        args.num_envs,
        config="paper",
        num_workers=args.num_workers,
        seed=args.seed,
        max_steps=500,
        stair_reward=50.0,
    )
    try:
        rng = np.random.default_rng(args.seed)
        batches = max(1, args.steps // args.num_envs)
        actions = rng.integers(0, 11, size=(256, args.num_envs))
        envs.reset()
        for i in range(20):  # warm-up
            envs.step(actions[i])
        returns: list[float] = []
        t0 = time.perf_counter()
        for i in range(batches):
            _, _, term, trunc, infos = envs.step(actions[i % 256])
            done = term | trunc
            if done.any():
                returns.extend(infos["episode_return"][done].tolist())
        dt = time.perf_counter() - t0
    finally:
        envs.close()
    sps = batches * args.num_envs / dt
    mean = float(np.mean(returns)) if returns else float("nan")
    print(
        f"pool: {args.num_envs} envs, {envs.num_workers} workers: {sps:,.0f} steps/s; "
        f"{len(returns)} episodes, mean score {mean:.1f}"
    )
    return sps


def run_async_vector_env(args: argparse.Namespace) -> float:
    import gymnasium as gym

    from rogue_gym.envs import RogueEnv

    def make() -> gym.Env:
        return RogueEnv(
            config_dict=rogue_gym.PAPER_CONFIG,
            max_steps=500,
            stair_reward=50.0,
            obs="symbol_onehot",
            dtype="uint8",
        )

    envs = gym.vector.AsyncVectorEnv([make] * args.num_envs, shared_memory=True)
    try:
        rng = np.random.default_rng(args.seed)
        batches = max(1, args.baseline_steps // args.num_envs)
        envs.reset(seed=args.seed)
        for _ in range(5):
            envs.step(rng.integers(0, 11, args.num_envs))
        t0 = time.perf_counter()
        for _ in range(batches):
            envs.step(rng.integers(0, 11, args.num_envs))
        dt = time.perf_counter() - t0
    finally:
        envs.close()
    sps = batches * args.num_envs / dt
    print(
        f"gymnasium AsyncVectorEnv(shared_memory=True), {args.num_envs} processes: {sps:,.0f} steps/s"
    )
    return sps


def main() -> None:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--num-envs", type=int, default=64)
    p.add_argument("--num-workers", type=int, default=min(2, rogue_gym._native.usable_cores()))
    p.add_argument("--steps", type=int, default=200_000, help="env steps to time")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--compare", action="store_true", help="also time gymnasium's AsyncVectorEnv")
    p.add_argument("--baseline-steps", type=int, default=20_000)
    args = p.parse_args()
    sps = run_pool(args)
    if args.compare:
        base = run_async_vector_env(args)
        print(f"speed-up: {sps / base:.1f}x")


if __name__ == "__main__":
    main()
