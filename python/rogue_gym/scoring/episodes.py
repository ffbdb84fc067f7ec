"""Playing a suite's scheduled episodes and attributing each return to its seed (see
:mod:`rogue_gym.evaluate`, "Episode schedule")."""

from __future__ import annotations

import sys
import time
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from ..suite_pool import obs_kwargs, suite_pool
from ..suites import Suite
from .policies import Policy, seed_policy

__all__ = ["InProcessVec", "final_seeds", "make_eval_pool", "run_episodes"]


def make_eval_pool(
    suite: Suite,
    seeds: List[int],
    num_envs: int,
    num_workers: Optional[int],
    obs: str,
) -> Any:
    """A gymnasium VectorEnv over the pool playing ``seeds`` round-robin (see module doc)."""
    kwargs: Dict[str, Any] = {}
    if num_workers is not None:
        kwargs["num_workers"] = num_workers
    return suite_pool(
        suite,
        num_envs,
        seeds=seeds,
        seed_policy="sequential",
        **obs_kwargs(obs),
        # A restarted worker would cut episodes short: an evaluation must fail loudly instead.
        on_worker_failure="raise",
        **kwargs,
    )


class InProcessVec:
    """The pool's evaluation semantics with ``RogueEnv`` games in this process (no workers).

    Same seed schedule (sequential round-robin over ``seeds``) and same-step autoreset as the
    pool, so given the same policy it yields the same returns: a cross-check of the pool, and
    a fallback where worker processes are unwanted (``--backend inprocess``).
    """

    def __init__(self, suite: Suite, seeds: List[int], num_envs: int, obs: str) -> None:
        from ..envs import RogueEnv

        self.seeds = list(seeds)
        self.num_envs = num_envs
        self.envs = [
            RogueEnv(
                config_dict=suite.config,
                max_steps=suite.max_steps,
                stair_reward=suite.stair_reward,
                **obs_kwargs(obs),
            )
            for _ in range(num_envs)
        ]
        self.episode = [0] * num_envs

    def _seed(self, i: int) -> int:
        return self.seeds[(i + self.episode[i] * self.num_envs) % len(self.seeds)]

    def reset(self) -> Tuple[np.ndarray, Dict[str, Any]]:
        """Start every env's first scheduled episode."""
        self.episode = [0] * self.num_envs
        obs = [e.reset(options={"episode_seed": self._seed(i)})[0] for i, e in enumerate(self.envs)]
        return np.stack(obs), {}

    def step(self, actions: np.ndarray) -> Tuple[Any, ...]:
        """Step every env; an ended episode is replaced by the next scheduled one at once."""
        obs, rew = [], np.zeros(self.num_envs)
        term = np.zeros(self.num_envs, bool)
        trunc = np.zeros(self.num_envs, bool)
        for i, env in enumerate(self.envs):
            o, r, te, tr, _ = env.step(int(actions[i]))
            rew[i], term[i], trunc[i] = r, te, tr
            if te or tr:
                self.episode[i] += 1
                o, _ = env.reset(options={"episode_seed": self._seed(i)})
            obs.append(o)
        return np.stack(obs), rew, term, trunc, {}

    def close(self) -> None:
        """Nothing to release."""


def run_episodes(
    suite: Suite,
    policy: Policy,
    seeds: Sequence[int],
    episodes_per_seed: int,
    num_envs: int = 16,
    num_workers: Optional[int] = None,
    obs: str = "symbol_onehot",
    policy_seed: int = 0,
    progress: bool = True,
    desc: str = "",
    backend: str = "pool",
    max_floor: Optional[np.ndarray] = None,
) -> np.ndarray:
    """Play ``episodes_per_seed`` episodes on each of ``seeds`` and return the returns.

    Returns a float64 array of shape ``(len(seeds), episodes_per_seed)``: row ``k`` holds the
    returns of the episodes played on ``seeds[k]``, in schedule order. ``backend`` is
    ``"pool"`` (worker processes, the default) or ``"inprocess"`` (:class:`InProcessVec`).
    ``max_floor``: an array of the same shape to fill with each episode's deepest floor (the
    pool's ``max_floor`` info; the pool backend only).
    """
    seeds = [int(s) for s in seeds]
    k, e_per = len(seeds), int(episodes_per_seed)
    if k == 0 or e_per <= 0:
        raise ValueError("need at least one seed and one episode per seed")
    total = k * e_per
    # No more envs than episodes; keep a multiple of the worker count (the pool needs one).
    num_envs = max(1, min(int(num_envs), total))
    if num_workers is not None and backend == "pool":
        w = int(num_workers)
        num_envs = max(w, num_envs // w * w)
    seed_policy(policy, policy_seed)
    # A policy that keeps a memory per env hears where episodes end (see evaluate's docs).
    ended_hook = getattr(policy, "episodes_ended", None)
    returns = np.full(total, np.nan, dtype=np.float64)
    deepest = np.zeros(total, dtype=np.int64)
    if backend == "pool":
        env = make_eval_pool(suite, seeds, num_envs, num_workers, obs)
    elif backend == "inprocess":
        env = InProcessVec(suite, seeds, num_envs, obs)
    else:
        raise ValueError(f"backend must be 'pool' or 'inprocess', got {backend!r}")
    bar = _progress(total, desc, progress)
    # The pool's one-line health summary beside the bar (an in-process run has none).
    health = getattr(env, "stats", None) if progress else None
    shown = time.monotonic()
    try:
        obs_batch, _ = env.reset()
        ep_index = np.arange(num_envs, dtype=np.int64)  # schedule index of each env's episode
        ep_return = np.zeros(num_envs, dtype=np.float64)
        done_count = 0
        while done_count < total:
            actions = np.asarray(policy(obs_batch), dtype=np.int64).reshape(num_envs)
            obs_batch, reward, terminated, truncated, info = env.step(actions)
            ep_return += np.asarray(reward, dtype=np.float64)
            ended = np.logical_or(terminated, truncated)
            if ended_hook is not None and ended.any():
                ended_hook(ended)
            finished = np.flatnonzero(ended)
            played = final_seeds(info)
            floors = _final(info, "max_floor") if max_floor is not None else None
            for i in finished:
                j = int(ep_index[i])
                if played is not None and int(played[i]) != seeds[j % k]:
                    raise RuntimeError(
                        f"env {i} played seed {int(played[i])}, the schedule says {seeds[j % k]}"
                    )
                if j < total:
                    returns[j] = ep_return[i]
                    if floors is not None:
                        deepest[j] = floors[i]
                    done_count += 1
                    bar.update(1)
                    if health is not None and time.monotonic() >= shown + 1.0:
                        bar.set_postfix_str(f"pool: {health()}", refresh=False)
                        shown = time.monotonic()
                ep_return[i] = 0.0
                ep_index[i] += num_envs
    finally:
        bar.close()
        env.close()
    # schedule index j = r * k + s  ->  (seed s, repetition r)
    if max_floor is not None:
        max_floor[...] = deepest.reshape(e_per, k).T
    return returns.reshape(e_per, k).T.copy()


def _final(info: Any, key: str) -> Optional[np.ndarray]:
    """Info ``key`` of the episodes that just ended, when the vector env reports it."""
    final = info.get("final_info") if isinstance(info, dict) else None
    if isinstance(final, dict) and key in final:
        return np.asarray(final[key])
    return None


def final_seeds(info: Any) -> Optional[np.ndarray]:
    """The seeds of the episodes that just ended, when the vector env reports them."""
    return _final(info, "seed")


class _NoBar:
    def update(self, n: int = 1) -> None:
        pass

    def set_postfix_str(self, text: str, refresh: bool = True) -> None:
        pass

    def close(self) -> None:
        pass


def _progress(total: int, desc: str, enabled: bool) -> Any:
    if not enabled:
        return _NoBar()
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm is a dev dependency
        return _NoBar()
    # Redraw at most every 0.1 s on a terminal, every 5 s into a log file.
    interval = 0.1 if sys.stderr.isatty() else 5.0
    return tqdm(
        total=total,
        desc=desc,
        unit="ep",
        dynamic_ncols=True,
        file=sys.stderr,
        mininterval=interval,
    )
