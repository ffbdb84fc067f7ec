"""``PoolVecEnv``: any gymnasium env in the pool's worker processes, with Stable-Baselines3's
``VecEnv`` API and ``SubprocVecEnv``'s contract (needs ``stable-baselines3``; imported by
:mod:`rogue_gym.sb3`).

It drives a :class:`~rogue_gym.hosted.PoolVectorEnv` in SAME_STEP mode and speaks SB3's
dialect: ``dones``, a list of info dicts with ``terminal_observation`` and
``TimeLimit.truncated``, ``reset_infos``, ``seed``/``set_options`` applied at the next reset,
and ``env_method``/``get_attr``/``set_attr``/``env_is_wrapped`` with ``indices``.
"""

from __future__ import annotations

import multiprocessing
import warnings
from typing import Any, Callable, Optional, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

from .vector_env import PoolVectorEnv, _VectorEnvFn

__all__ = ["PoolVecEnv"]


def _row(infos: dict[str, Any], i: int) -> dict[str, Any]:
    """Env ``i``'s entries of a gymnasium vector info dict (nested dicts included)."""
    out: dict[str, Any] = {}
    for key, value in infos.items():
        if key.startswith("_") or not infos.get(f"_{key}", np.zeros(i + 1, bool))[i]:
            continue
        out[key] = _row(value, i) if isinstance(value, dict) else value[i]
    return out


class PoolVecEnv(VecEnv):
    """``len(env_fns)`` gymnasium envs in worker processes, as an SB3 ``VecEnv`` (a drop-in for
    ``SubprocVecEnv``: ``make_vec_env(..., vec_env_cls=PoolVecEnv)`` works).

    Args:
        env_fns: one callable per env (cloudpickled).
        start_method: accepted for ``SubprocVecEnv`` compatibility; workers are always fresh
            processes (``python -m rogue_gym.worker``), never forks.
        **options: keywords of :class:`~rogue_gym.hosted.PoolVectorEnv` (``num_workers``,
            ``on_worker_failure``, ``step_timeout``, ``max_restarts``, ``info_bytes``, ...).

    A restarted worker's envs end their episode: ``dones[i]`` is true,
    ``infos[i]["TimeLimit.truncated"]`` and ``infos[i]["worker_restarted"]`` are set, and
    ``terminal_observation`` is the first observation of the rebuilt env.

    **Array lifetimes.** Observations are fresh copies; rewards, dones and infos too.
    """

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gym.Env]],
        start_method: Optional[str] = None,
        **options: Any,
    ) -> None:
        if start_method is not None:
            # Workers are never forked, but a bad name is still the error SubprocVecEnv raises.
            multiprocessing.get_context(start_method)
        options["autoreset_mode"] = AutoresetMode.SAME_STEP
        self.venv = PoolVectorEnv(env_fns, **options)
        self._actions: Any = None
        super().__init__(
            self.venv.num_envs, self.venv.single_observation_space, self.venv.single_action_space
        )

    @classmethod
    def from_vector_env(
        cls, vector_env_fn: Callable[[int], gym.vector.VectorEnv], num_envs: int, **options: Any
    ) -> PoolVecEnv:
        """``num_envs`` envs hosted as one gymnasium vector env per worker block (see
        :meth:`rogue_gym.hosted.PoolVectorEnv.from_vector_env`), as an SB3 ``VecEnv``. The
        vector env must autoreset ``SAME_STEP``, SB3's convention, e.g.
        ``lambda n: AtariVectorEnv("pong", num_envs=n, num_threads=1,
        autoreset_mode="SameStep")``. ``set_attr`` is not available; reset options reach
        every env of the block."""
        return cls(_VectorEnvFn(vector_env_fn, int(num_envs)), **options)  # type: ignore[arg-type]

    # -- stepping --------------------------------------------------------------------------

    def reset(self) -> VecEnvObs:
        if any(o for o in self._options):
            for i, opts in enumerate(self._options):
                self.venv.call_envs("set_reset_options", "", [((opts or None,), {})], [i])
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        if seeds is not None and any(s is None for s in seeds):
            raise ValueError("seed() must seed every env (or none) before reset()")
        obs, infos = self.venv.reset(seed=seeds)
        self.reset_infos = [_row(infos, i) for i in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        space = self.action_space
        if isinstance(actions, list) and isinstance(space, (spaces.Dict, spaces.Tuple)):
            actions = _stack(actions, space)  # one action per env, as DummyVecEnv takes them
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, terminated, truncated, infos = self.venv.step(self._actions)
        dones = terminated | truncated
        out: list[dict[str, Any]] = []
        for i in range(self.num_envs):
            top = _row(infos, i)
            if not dones[i]:
                top["TimeLimit.truncated"] = False  # on every step, as SubprocVecEnv
                out.append(top)
                continue
            info = dict(top.pop("final_info", {}))
            final_obs = top.pop("final_obs", None)
            if final_obs is None:  # a restarted worker: no last observation survives
                final_obs = _first_obs(obs, i)
            info["terminal_observation"] = final_obs
            info["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            if top.pop("worker_restarted", False):
                info["worker_restarted"] = True
            self.reset_infos[i] = top
            out.append(info)
        return obs, rewards.astype(np.float32), dones, out

    # -- calls -----------------------------------------------------------------------------

    def _on(
        self, op: str, name: str, indices: VecEnvIndices, *args: Any, **kwargs: Any
    ) -> list[Any]:
        envs = [int(i) % self.num_envs for i in self._get_indices(indices)]
        return self.venv.call_envs(op, name, [(args, kwargs)] * len(envs), envs)

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return self._on("get_attr", attr_name, indices)

    def has_attr(self, attr_name: str) -> bool:
        return all(self._on("has_attr", attr_name, None))

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        self._on("setattr", attr_name, indices, value)

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        return self._on("env_method", method_name, indices, *method_args, **method_kwargs)

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        return self._on("is_wrapped", "", indices, wrapper_class)

    def get_images(self) -> Sequence[Optional[np.ndarray]]:
        if self.render_mode != "rgb_array":
            warnings.warn(
                f"The render mode is {self.render_mode}, but this method assumes it is `rgb_array` to obtain images.",
                stacklevel=2,
            )
            return [None] * self.num_envs
        return list(self.venv.render())

    def close(self) -> None:
        self.venv.close()

    @property
    def restarts(self) -> int:
        """Worker restarts so far."""
        return self.venv.restarts

    @property
    def worker_pids(self) -> list[int]:
        """Process ids of the workers."""
        return self.venv.worker_pids


def _stack(actions: list[Any], space: spaces.Space) -> Any:
    """A list of per-env actions of a Dict or Tuple space as one batch."""
    if isinstance(space, spaces.Dict):
        return {k: _stack([a[k] for a in actions], sub) for k, sub in space.spaces.items()}
    if isinstance(space, spaces.Tuple):
        return tuple(_stack([a[i] for a in actions], sub) for i, sub in enumerate(space.spaces))
    return np.stack([np.asarray(a) for a in actions])


def _first_obs(obs: Any, i: int) -> Any:
    if isinstance(obs, dict):
        return {k: _first_obs(v, i) for k, v in obs.items()}
    if isinstance(obs, tuple):
        return tuple(_first_obs(v, i) for v in obs)
    return obs[i].copy()
