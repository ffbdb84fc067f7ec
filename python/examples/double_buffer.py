"""Double buffering, CleanRL-shaped: the policy acts on one half of the envs while the workers
step the other half.

``batch_size = num_envs // 2`` makes the pool's async API hand over one half at a time, the
first ready first: ``recv()`` returns a half (its rows written in place by the workers, valid
until the next ``recv``), the policy picks their actions, and ``send()`` starts them stepping
while the next ``recv()`` takes the other half. With a policy as slow as the envs, this runs up
to twice as many steps a second as ``step()`` on all envs (docs/performance.md, "Double
buffering").

    python python/examples/double_buffer.py --num-envs 64 --total-steps 200000
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch
from torch import nn
from torch.distributions import Categorical

import rogue_gym


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--num-envs", type=int, default=64, help="envs (two halves of num_envs/2)")
    p.add_argument("--num-workers", type=int, default=1, help="worker processes")
    p.add_argument("--total-steps", type=int, default=200_000, help="env steps to run")
    p.add_argument("--seed", type=int, default=1)
    return p.parse_args()


class Agent(nn.Module):
    """A small policy over the game's symbol planes."""

    def __init__(self, obs_shape: tuple[int, ...], num_actions: int) -> None:
        super().__init__()
        self.net = nn.Sequential(
            nn.Flatten(),
            nn.Linear(int(np.prod(obs_shape)), 64),
            nn.Tanh(),
            nn.Linear(64, num_actions),
        )

    def act(self, obs: torch.Tensor) -> torch.Tensor:
        return Categorical(logits=self.net(obs)).sample()


def main() -> None:
    args = parse_args()
    torch.manual_seed(args.seed)
    envs = rogue_gym.make_vec(
        "RogueGym-v0",
        num_envs=args.num_envs,
        batch_size=args.num_envs // 2,
        num_workers=args.num_workers,
        max_steps=500,
    )
    agent = Agent(envs.single_observation_space.shape, int(envs.single_action_space.n))
    returns: list[float] = []

    envs.async_reset(seed=args.seed)
    global_step, start = 0, time.perf_counter()
    while global_step < args.total_steps:
        # One half, the first ready: views of the rows the workers wrote, until the next recv.
        obs, reward, terminated, truncated, info = envs.recv()
        env_id = info["env_id"]
        with torch.no_grad():
            action = agent.act(torch.as_tensor(obs, dtype=torch.float32))
        # The workers step this half while the next recv() takes the other.
        envs.send(action.numpy(), env_id)
        global_step += len(env_id)
        ended = terminated | truncated
        if ended.any():
            returns.extend(info["episode_return"][ended].tolist())
    sps = global_step / (time.perf_counter() - start)
    envs.recv()  # the last half in flight
    envs.close()
    mean = f"{np.mean(returns):.2f}" if returns else "n/a"
    print(f"{global_step} steps, {sps:,.0f} steps/s, {len(returns)} episodes, mean return {mean}")


if __name__ == "__main__":
    main()
