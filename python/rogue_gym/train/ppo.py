"""The PPO update: generalized advantage estimation and clipped policy/value losses.

Everything stays on the device in whole tensors: one GAE pass over the rollout, then for each
epoch one permutation of the batch and one forward/backward per minibatch. The losses follow
the paper's code (Rainy): the clipped surrogate objective, a clipped value loss (the larger of
the clipped and unclipped squared errors), an entropy bonus, advantages normalized per
minibatch (once per rollout under ``--compat original``, as Rainy 0.1 does), and the global
gradient norm clipped. An episode end (termination, the 500-step
limit, or a worker restart) cuts the return there, as in the paper's code.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict

import torch
import torch.nn.functional as F

from .config import TrainConfig
from .networks import PolicyNet
from .rollout import Rollout

__all__ = ["compute_gae", "ppo_update"]


def compute_gae(
    rewards: torch.Tensor,
    values: torch.Tensor,
    dones: torch.Tensor,
    last_values: torch.Tensor,
    gamma: float,
    lam: float,
) -> torch.Tensor:
    """Advantages ``(T, N)`` by GAE(lambda); ``dones[t]`` ends the episode with step ``t``."""
    steps = rewards.shape[0]
    adv = torch.zeros_like(rewards)
    carry = torch.zeros_like(last_values)
    next_values = last_values
    for t in reversed(range(steps)):
        alive = 1.0 - dones[t]
        delta = rewards[t] + gamma * next_values * alive - values[t]
        carry = delta + gamma * lam * alive * carry
        adv[t] = carry
        next_values = values[t]
    return adv


@dataclass
class UpdateStats:
    """Means over an update's minibatches."""

    policy_loss: float
    value_loss: float
    entropy: float
    aux_loss: float
    approx_kl: float
    clip_fraction: float

    def as_dict(self) -> Dict[str, float]:
        """Column name -> value."""
        return dict(self.__dict__)


def ppo_update(
    net: PolicyNet,
    optimizer: torch.optim.Optimizer,
    buf: Rollout,
    cfg: TrainConfig,
    generator: torch.Generator,
) -> UpdateStats:
    """``cfg.epochs`` epochs of minibatch PPO on ``buf``; returns the mean losses."""
    adv = compute_gae(
        buf.rewards, buf.values, buf.dones, buf.last_values, cfg.gamma, cfg.gae_lambda
    )
    returns = (adv + buf.values).flatten()
    adv = adv.flatten()
    obs = buf.obs.flatten(0, 1)
    actions = buf.actions.flatten()
    old_logp = buf.logprobs.flatten()
    old_values = buf.values.flatten()
    whole_rollout = cfg.compat == "original"
    if whole_rollout:  # Rainy 0.1: rainy/lib/rollout.py:147-149, eps 1e-5
        adv = (adv - adv.mean()) / (adv.std() + 1e-5)
    n, mb = adv.shape[0], int(cfg.minibatch_size or 0)
    sums = torch.zeros(6, device=adv.device)
    count = 0
    net.train()
    for _ in range(cfg.epochs):
        perm = torch.randperm(n, generator=generator).to(adv.device)
        for start in range(0, n - mb + 1, mb):
            idx = perm[start : start + mb]
            out = net(obs[idx], with_aux=True)
            logp_all = F.log_softmax(out.logits, dim=-1)
            logp = logp_all.gather(1, actions[idx].unsqueeze(1)).squeeze(1)
            entropy = -(logp_all.exp() * logp_all).sum(-1).mean()
            log_ratio = logp - old_logp[idx]
            ratio = log_ratio.exp()
            a = adv[idx]
            if not whole_rollout:
                a = (a - a.mean()) / (a.std() + 1e-5)
            pg_loss = -torch.min(ratio * a, ratio.clamp(1.0 - cfg.clip, 1.0 + cfg.clip) * a).mean()
            v, v_old, ret = out.value, old_values[idx], returns[idx]
            v_clipped = v_old + (v - v_old).clamp(-cfg.clip, cfg.clip)
            v_loss = torch.max((v - ret).pow(2), (v_clipped - ret).pow(2)).mean()
            loss = pg_loss + cfg.value_coef * v_loss - cfg.entropy_coef * entropy
            aux = out.aux_loss if out.aux_loss is not None else torch.zeros((), device=a.device)
            loss = loss + aux
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), cfg.max_grad_norm)
            optimizer.step()
            with torch.no_grad():
                approx_kl = ((ratio - 1.0) - log_ratio).mean()
                clipped = ((ratio - 1.0).abs() > cfg.clip).float().mean()
                sums += torch.stack(
                    [
                        pg_loss.detach(),
                        v_loss.detach(),
                        entropy.detach(),
                        aux.detach(),
                        approx_kl,
                        clipped,
                    ]
                )
            count += 1
    means = (sums / max(count, 1)).tolist()
    return UpdateStats(*means)
