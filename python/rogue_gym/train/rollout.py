"""Collecting rollouts from the pool, with the env stepping while the policy thinks.

The training pool runs in the async (send/recv) mode with ``batch_size`` = the envs of one
worker, so each ``recv`` hands over one worker's block of envs. With the default two workers
these are two halves: while the policy picks actions for the half just received, the other
half's worker is stepping. Each group plays ``num_steps`` steps per rollout; the buffer is
indexed by (step, env), so the order in which groups arrive does not matter.

**Determinism.** Actions are sampled with the Gumbel-max trick from noise drawn up front for the
whole rollout, ``noise[t, env]``, so a sampled action depends on its env and step only, never on
which worker the pool returned first. Episode seeds come from the pool's schedule (base seed and
env index). So on the CPU a given seed gives the same rollouts, update after update.

Observations travel as symbol indices (``uint8``, ``(16, 32)`` per env) and are copied once
into a device buffer (pinned and non-blocking on CUDA); the networks one-hot them implicitly
(:class:`~rogue_gym.train.networks.OneHotConv2d`).
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Deque, List, Optional

import numpy as np
import torch
import torch.nn.functional as F

from .networks import PolicyNet

__all__ = ["Collector", "EpisodeStats", "Rollout"]


@dataclass
class Rollout:
    """One update's worth of transitions, ``(num_steps, num_envs)`` tensors on the device.

    ``dones[t]`` says the episode ended with step ``t`` (terminated, truncated, or its worker
    restarted); ``obs[t + 1]`` is then the next episode's first screen. ``last_obs`` and
    ``last_values`` are the screens and values after the final step (for bootstrapping).
    """

    obs: torch.Tensor
    actions: torch.Tensor
    logprobs: torch.Tensor
    values: torch.Tensor
    rewards: torch.Tensor
    dones: torch.Tensor
    last_values: torch.Tensor

    @classmethod
    def empty(cls, steps: int, envs: int, obs_shape: tuple, device: torch.device) -> Rollout:
        """Zeroed buffers for ``steps x envs`` transitions."""

        def z(*shape: int, dtype: torch.dtype = torch.float32) -> torch.Tensor:
            return torch.zeros(shape, dtype=dtype, device=device)

        return cls(
            obs=z(steps, envs, *obs_shape, dtype=torch.uint8),
            actions=z(steps, envs, dtype=torch.int64),
            logprobs=z(steps, envs),
            values=z(steps, envs),
            rewards=z(steps, envs),
            dones=z(steps, envs),
            last_values=z(envs),
        )


@dataclass
class EpisodeStats:
    """Returns of finished training episodes: the training score is the mean of the last 1000."""

    window: int = 1000
    returns: Deque[float] = field(default_factory=deque)
    episodes: int = 0

    def __post_init__(self) -> None:
        self.returns = deque(self.returns, maxlen=self.window)

    def add(self, values: np.ndarray) -> None:
        """Record the returns of episodes that just ended."""
        self.returns.extend(float(v) for v in values)
        self.episodes += len(values)

    def score(self) -> float:
        """Mean return of the last ``window`` episodes (NaN before the first one ends)."""
        return float(np.mean(self.returns)) if self.returns else float("nan")

    def state_dict(self) -> dict:
        """For checkpoints."""
        return {"returns": list(self.returns), "episodes": self.episodes}

    def load_state_dict(self, state: dict) -> None:
        """Restore :meth:`state_dict`."""
        self.returns = deque(state["returns"], maxlen=self.window)
        self.episodes = int(state["episodes"])


@dataclass
class _Group:
    """One worker's group of envs (a half, with two workers): its env ids and its latest
    screens (received, not yet answered)."""

    ids: np.ndarray
    ids_t: torch.Tensor
    obs: Optional[torch.Tensor] = None
    step: int = 0
    staging: Optional[torch.Tensor] = None


class Collector:
    """Steps a pool's envs in overlapping worker groups and fills :class:`Rollout` buffers.

    ``env`` is a :class:`rogue_gym.RogueVectorEnv` built with ``obs="symbol_index"``,
    ``autoreset_mode=SAME_STEP`` and ``batch_size`` = the envs of one worker (with one worker,
    nothing overlaps).
    """

    def __init__(self, env: Any, num_steps: int, device: torch.device, seed: int) -> None:
        self.env = env
        self.num_envs = int(env.num_envs)
        self.num_steps = num_steps
        self.device = device
        self.obs_shape = tuple(env.single_observation_space.shape)
        self.num_actions = int(env.single_action_space.n)
        self.generator = torch.Generator(device="cpu")
        self.generator.manual_seed(seed)
        self.stats = EpisodeStats()
        self.pin = device.type == "cuda"
        self._groups: List[_Group] = []
        self._running = torch.zeros(self.num_envs, dtype=torch.float64)
        self.env_seconds = 0.0
        self.policy_seconds = 0.0
        #: Envs whose episode a worker restart cut short (each reports ``truncated``).
        self.restarted_envs = 0

    def start(self) -> None:
        """Reset every env and receive the first screens."""
        self.env.async_reset()
        self._groups = []
        received = 0
        while received < self.num_envs:
            t0 = time.perf_counter()
            obs, _, _, _, info = self.env.recv()
            self.env_seconds += time.perf_counter() - t0
            ids = np.asarray(info["env_id"], dtype=np.int64)
            group = _Group(ids, torch.from_numpy(ids).to(self.device))
            group.obs = self._to_device(obs, group)
            self._groups.append(group)
            received += len(ids)
        self._groups.sort(key=lambda h: int(h.ids[0]))
        self._running.zero_()

    def _to_device(self, obs: np.ndarray, group: _Group) -> torch.Tensor:
        """A device copy of a received batch (the shared-memory sample is only borrowed).

        On CUDA the screens go through the group's pinned staging buffer with a non-blocking
        copy; the buffer is rewritten only after the group's next actions came back to the
        host, which waits for that copy.
        """
        if not self.pin:
            return torch.from_numpy(np.array(obs, copy=True)).to(self.device)
        if group.staging is None or group.staging.shape != obs.shape:
            group.staging = torch.empty(obs.shape, dtype=torch.uint8).pin_memory()
        group.staging.numpy()[...] = obs
        return group.staging.to(self.device, non_blocking=True)

    def _group_of(self, first_id: int) -> _Group:
        for h in self._groups:
            if int(h.ids[0]) == first_id:
                return h
        raise RuntimeError(f"the pool returned an unexpected block starting at env {first_id}")

    @torch.no_grad()
    def _act(self, net: PolicyNet, group: _Group, buf: Rollout, noise: torch.Tensor) -> None:
        t0 = time.perf_counter()
        assert group.obs is not None
        t, ids = group.step, group.ids_t
        out = net(group.obs)
        logp = F.log_softmax(out.logits, dim=-1)
        action = torch.argmax(logp + noise[t, ids], dim=-1)
        buf.obs[t, ids] = group.obs
        buf.actions[t, ids] = action
        buf.logprobs[t, ids] = logp.gather(1, action.unsqueeze(1)).squeeze(1)
        buf.values[t, ids] = out.value
        actions = action.cpu().numpy()
        self.policy_seconds += time.perf_counter() - t0
        self.env.send(actions, group.ids)

    @torch.no_grad()
    def collect(self, net: PolicyNet, buf: Rollout, train_mode: bool = False) -> None:
        """Play ``num_steps`` steps in every env with ``net`` into ``buf``: in eval mode, or in
        train mode with ``train_mode`` (``--compat original``: BatchNorm then normalises each
        batch of screens by its own statistics, as the paper's code did)."""
        if not self._groups:
            self.start()
        was_training = net.training
        net.train(train_mode)
        # Gumbel noise for every (step, env, action): sampling independent of arrival order.
        u = torch.rand((self.num_steps, self.num_envs, self.num_actions), generator=self.generator)
        noise = (-torch.log(-torch.log(u.clamp_(1e-12, 1.0 - 1e-7)))).to(self.device)
        for group in self._groups:
            group.step = 0
            self._act(net, group, buf, noise)
        outstanding = len(self._groups)
        while outstanding:
            t0 = time.perf_counter()
            obs, reward, terminated, truncated, info = self.env.recv()
            self.env_seconds += time.perf_counter() - t0
            ids = info["env_id"]
            group = self._group_of(int(ids[0]))
            done = np.logical_or(terminated, truncated)
            if "worker_restarted" in info:
                restarted = np.asarray(info["worker_restarted"], dtype=bool)
                self.restarted_envs += int(restarted.sum())
                done |= restarted
            t = group.step
            buf.rewards[t, group.ids_t] = torch.as_tensor(reward, dtype=torch.float32).to(
                self.device
            )
            buf.dones[t, group.ids_t] = torch.as_tensor(done, dtype=torch.float32).to(self.device)
            self._track(group.ids, reward, done)
            group.obs = self._to_device(obs, group)
            group.step += 1
            if group.step < self.num_steps:
                self._act(net, group, buf, noise)
            else:
                outstanding -= 1
        for group in self._groups:
            assert group.obs is not None
            buf.last_values[group.ids_t] = net(group.obs).value
        net.train(was_training)

    def _track(self, ids: np.ndarray, reward: np.ndarray, done: np.ndarray) -> None:
        run = self._running
        idx = torch.from_numpy(ids)
        run[idx] += torch.from_numpy(np.asarray(reward, dtype=np.float64))
        if done.any():
            ended = idx[torch.from_numpy(done)]
            self.stats.add(run[ended].numpy())
            run[ended] = 0.0
