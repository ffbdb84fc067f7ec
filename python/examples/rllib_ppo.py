"""RLlib PPO on Rogue-Gym, every EnvRunner stepping its envs through one pool.

Needs the Ray environment: ``bash scripts/setup-ray.sh``, then::

    .venv-ray/bin/python python/examples/rllib_ppo.py                 # 6 iterations, ~2 min
    .venv-ray/bin/python python/examples/rllib_ppo.py --address auto  # on a running cluster

On a cluster, raise ``--env-runners`` (one per node or more) and ``--num-workers`` (pool worker
processes per runner, about the cores a runner may use). Fault tolerance: see docs/ray.md.
"""

from __future__ import annotations

import argparse
import time

import ray
from ray.rllib.algorithms.ppo import PPOConfig

from rogue_gym.ray import configure_rllib


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    # 1000 env steps per iteration; with 8 envs, the first 500-step episodes end in the 4th.
    p.add_argument("--iterations", type=int, default=6)
    p.add_argument("--env-runners", type=int, default=1)
    p.add_argument("--envs-per-runner", type=int, default=8)
    p.add_argument("--num-workers", type=int, default=1, help="pool workers per EnvRunner")
    p.add_argument("--address", default=None, help="a Ray cluster to join (default: local)")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()

    ray.init(address=args.address, include_dashboard=False)
    config = (
        PPOConfig()
        # The paper's PPO: 10 epochs, clip 0.1, gamma 0.99, lambda 0.95, lr 2.5e-4, entropy 0.01.
        .training(
            train_batch_size_per_learner=1000,
            minibatch_size=200,
            num_epochs=10,
            clip_param=0.1,
            gamma=0.99,
            lambda_=0.95,
            lr=2.5e-4,
            vf_loss_coeff=0.5,
            entropy_coeff=0.01,
        )
        .fault_tolerance(
            restart_failed_env_runners=True,
            max_num_env_runner_restarts=100,
            delay_between_env_runner_restarts_s=10.0,
        )
        .debugging(seed=args.seed)
    )
    config = configure_rllib(
        config,
        "RogueGym-v0",
        num_env_runners=args.env_runners,
        num_envs_per_env_runner=args.envs_per_runner,
        num_workers=args.num_workers,
        obs="symbol_index",  # (16, 32) uint8 symbols; one-hot on the learner's device
    )
    algo = config.build_algo()
    start = time.monotonic()
    try:
        for i in range(args.iterations):
            r = algo.train()["env_runners"]
            episodes = int(r.get("num_episodes_lifetime", 0))
            score = (
                f"mean return {r['episode_return_mean']:.1f}"
                if episodes
                else "no episode has ended yet"
            )
            print(
                f"iteration {i + 1}/{args.iterations}: "
                f"{int(r['num_env_steps_sampled_lifetime'])} env steps, {episodes} episodes, "
                f"{score}, {time.monotonic() - start:.0f} s",
                flush=True,
            )
    finally:
        algo.stop()
        ray.shutdown()


if __name__ == "__main__":
    main()
