"""Train PPO (Stable-Baselines3) on the paper's training seeds through the environment pool.

A short smoke-sized run by default; raise ``--timesteps`` for real training (the paper used 40M
frames, 32 envs x 125 steps per update). Needs ``stable-baselines3`` (and torch).

    python python/examples/ppo_sb3.py --timesteps 20000
"""

from __future__ import annotations

import argparse

import rogue_gym
from rogue_gym.sb3 import RogueVecEnv


def main() -> None:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--timesteps", type=int, default=8000)
    p.add_argument("--num-envs", type=int, default=32)
    p.add_argument("--num-workers", type=int, default=2)
    p.add_argument("--train-seeds", type=int, default=40, help="train on dungeons [0, N)")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()

    from stable_baselines3 import PPO

    env = RogueVecEnv(
        args.num_envs,
        config=rogue_gym.PAPER_CONFIG,
        num_workers=args.num_workers,
        seeds=range(args.train_seeds),
        seed=args.seed,
        max_steps=500,
        obs="symbol_index",  # (16, 32) uint8; one-hot it in the network for a CNN
    )
    try:
        model = PPO(
            "MlpPolicy",
            env,
            n_steps=125,
            batch_size=400,
            learning_rate=2.5e-4,
            seed=args.seed,
            verbose=1,
        )
        model.learn(total_timesteps=args.timesteps)
    finally:
        env.close()


if __name__ == "__main__":
    main()
