"""``FrontVecEnv``: the pool as a Stable-Baselines3 ``VecEnv``, for every env kind (needs
``stable-baselines3``).

It drives a :class:`rogue_gym.front.vector_env.FrontVectorEnv` in SAME_STEP mode and speaks
SB3's dialect (``SubprocVecEnv``'s contract): ``dones``, a list of info dicts with
``terminal_observation``, ``TimeLimit.truncated`` and, at an episode's end, the ``episode``
info of SB3's ``Monitor``; ``reset_infos``; ``seed``/``set_options`` applied at the next
reset; ``env_method``/``get_attr``/``set_attr``/``env_is_wrapped`` with ``indices``.
"""

from __future__ import annotations

import time
import warnings
from typing import Any, Optional, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

from ..kinds.result import copy_tree, row_of
from .stats import PoolStats
from .vector_env import FrontVectorEnv

__all__ = ["FrontVecEnv", "info_rows"]

#: Keys of gymnasium's SAME_STEP infos that SB3 carries otherwise.
_FINAL_KEYS = ("final_obs", "final_info")


def info_rows(infos: dict[str, Any], n: int, skip: Sequence[str] = ()) -> list[dict[str, Any]]:
    """The per-env dicts of gymnasium vector infos (an entry where its ``_key`` mask is set;
    nested dicts too), one list per key rather than one lookup per env and key."""
    rows: list[dict[str, Any]] = [{} for _ in range(n)]
    for key, value in infos.items():
        if key.startswith("_") or key in skip:
            continue
        mask = infos.get(f"_{key}")
        if mask is None:
            continue
        envs = range(n) if mask.all() else np.flatnonzero(mask).tolist()
        if isinstance(value, dict):
            value = info_rows(value, n)
        elif isinstance(value, np.ndarray) and value.ndim == 1 and value.dtype != object:
            value = value.tolist()  # plain Python numbers, in one go
        for i in envs:
            rows[i][key] = value[i]
    return rows


class FrontVecEnv(VecEnv):
    """An SB3 ``VecEnv`` over ``venv`` (a :class:`FrontVectorEnv` in SAME_STEP mode).

    * When an episode ends, ``step_wait`` returns the next episode's first observation, with
      ``infos[i]["terminal_observation"]`` (the last observation), the last step's info,
      ``TimeLimit.truncated = truncated and not terminated``, and ``episode`` = ``{"r":
      return, "l": length, "t": seconds since creation}`` as SB3's ``Monitor`` writes it
      (an env's own ``episode`` info, e.g. from a ``Monitor`` wrapper, is kept).
    * A restarted worker's envs end their episode as truncated (``TimeLimit.truncated`` and
      ``worker_restarted`` set, ``terminal_observation`` the last observation returned
      before, no ``episode``: its counters died with the worker).
    """

    def __init__(self, venv: FrontVectorEnv) -> None:
        self.venv = venv
        self._actions: Any = None
        self._last_obs: Any = None
        self._t0 = time.perf_counter()
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)

    # -- the pool --------------------------------------------------------------------------

    @property
    def num_workers(self) -> int:
        """Number of worker processes."""
        return self.venv.num_workers

    @property
    def worker_pids(self) -> list[int]:
        """Process ids of the workers."""
        return self.venv.worker_pids

    @property
    def restarts(self) -> int:
        """Worker restarts so far."""
        return self.venv.restarts

    def envs_of_worker(self, worker: int) -> range:
        """Indices of the envs hosted by ``worker``."""
        return self.venv.envs_of_worker(worker)

    def stats(self, reset: bool = False) -> PoolStats:
        """The pool's statistics (see :meth:`FrontVectorEnv.stats`)."""
        return self.venv.stats(reset)

    # -- stepping --------------------------------------------------------------------------

    def reset(self) -> VecEnvObs:
        """Reset every env with the seeds and options given since the last reset."""
        if any(self._options):
            for i, opts in enumerate(self._options):
                self.venv.call_envs("set_reset_options", "", [((opts or None,), {})], [i])
        seeds = self._seeds
        seed: Any = None
        if any(s is not None for s in seeds):
            if any(s is None for s in seeds):
                raise ValueError("seed() must seed every env (or none) before reset()")
            first = int(seeds[0])  # type: ignore[arg-type]
            # SB3's seed(s) gives env i the seed s + i: every kind takes that as one int.
            seed = first if list(seeds) == list(range(first, first + self.num_envs)) else seeds
        obs, infos = self.venv.reset(seed=seed)
        self.reset_infos = info_rows(infos, self.num_envs)
        self._reset_seeds()
        self._reset_options()
        self._last_obs = obs
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        """Keep the actions (one per env) for :meth:`step_wait`."""
        space = self.action_space
        if isinstance(actions, list) and isinstance(space, (spaces.Dict, spaces.Tuple)):
            actions = _stack(actions, space)  # one action per env, as DummyVecEnv takes them
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        """Step every env; ``(obs, rewards, dones, infos)``."""
        actions, self._actions = self._actions, None
        if actions is None:
            raise RuntimeError("step_wait() called without step_async()")
        prev_obs = self._last_obs
        obs, rewards, terminated, truncated, infos = self.venv.step(actions)
        dones = terminated | truncated
        n = self.num_envs
        rows = info_rows(infos, n, _FINAL_KEYS)
        cut = (truncated & ~terminated).tolist()
        for i in range(n):
            rows[i]["TimeLimit.truncated"] = cut[i]  # on every step, as SubprocVecEnv
        ended = np.flatnonzero(dones)
        if len(ended):
            has_final = infos.get("_final_obs")
            finals = info_rows(infos["final_info"], n) if "final_info" in infos else None
            ret, length = self.venv.episode_counters()
            now = round(time.perf_counter() - self._t0, 6)
            for i in ended.tolist():
                top = rows[i]
                restarted = bool(top.pop("worker_restarted", False))
                if has_final is not None and has_final[i] and finals is not None:
                    info = finals[i]
                    info["terminal_observation"] = infos["final_obs"][i]
                else:  # a restarted worker: the last observation returned stands for it
                    info = dict(top)
                    info["terminal_observation"] = copy_tree(row_of(prev_obs, i))
                info["TimeLimit.truncated"] = cut[i]
                if restarted:
                    info["worker_restarted"] = True
                else:
                    info.setdefault("episode", {"r": float(ret[i]), "l": int(length[i]), "t": now})
                self.reset_infos[i] = top
                rows[i] = info
        self._last_obs = obs
        return obs, rewards.astype(np.float32), dones, rows

    def close(self) -> None:
        """Stop the workers and remove the pool's shared-memory files (idempotent)."""
        self.venv.close()

    # -- calls -----------------------------------------------------------------------------

    def _on(
        self, op: str, name: str, indices: VecEnvIndices, *args: Any, **kwargs: Any
    ) -> list[Any]:
        envs = [int(i) % self.num_envs for i in self._get_indices(indices)]
        return self.venv.call_envs(op, name, [(args, kwargs)] * len(envs), envs)

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The attribute of the envs ``indices``."""
        if getattr(self, "venv", None) is None:
            raise AttributeError(attr_name)
        return self._on("get_attr", attr_name, indices)

    def has_attr(self, attr_name: str) -> bool:
        """Whether every env has the attribute."""
        return all(self._on("has_attr", attr_name, None))

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set the attribute in the envs ``indices``."""
        self._on("setattr", attr_name, indices, value)

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        """Call a method of the envs ``indices``."""
        return self._on("env_method", method_name, indices, *method_args, **method_kwargs)

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        """Whether the envs ``indices`` are wrapped by ``wrapper_class``."""
        return self._on("is_wrapped", "", indices, wrapper_class)

    def get_images(self) -> Sequence[Optional[np.ndarray]]:
        """One RGB image per env (``render_mode="rgb_array"``)."""
        if self.render_mode != "rgb_array":
            warnings.warn(
                f"The render mode is {self.render_mode}, but this method assumes it is `rgb_array` to obtain images.",
                stacklevel=2,
            )
            return [None] * self.num_envs
        return list(self.venv.render() or ())


def _stack(actions: list[Any], space: spaces.Space) -> Any:
    """A list of per-env actions of a Dict or Tuple space as one batch."""
    if isinstance(space, spaces.Dict):
        return {k: _stack([a[k] for a in actions], sub) for k, sub in space.spaces.items()}
    if isinstance(space, spaces.Tuple):
        return tuple(_stack([a[i] for a in actions], sub) for i, sub in enumerate(space.spaces))
    return np.stack([np.asarray(a) for a in actions])
