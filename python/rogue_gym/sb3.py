"""The pool as a Stable-Baselines3 ``VecEnv`` (needs ``stable-baselines3``).

* :class:`RogueVecEnv`: the native game.
* :class:`PoolVecEnv`: any gymnasium env (a drop-in for ``SubprocVecEnv``; defined in
  :mod:`rogue_gym.hosted.sb3_vec_env`).

Import them explicitly (``from rogue_gym.sb3 import RogueVecEnv``): ``import rogue_gym`` does
not import SB3 or torch.
"""

from __future__ import annotations

import time
from typing import Any, Iterable, Optional, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices

from ._config import ConfigLike
from ._core import ActionHistory, PoolCore, PoolFacade, screen_to_rgb
from .envs.rogue_env import ACTIONS
from .hosted.sb3_vec_env import PoolVecEnv
from .settings import PoolSettings

__all__ = ["PoolVecEnv", "RogueVecEnv"]


class RogueVecEnv(VecEnv, PoolFacade):
    """``num_envs`` Rogue-Gym games in worker processes, with SB3's ``VecEnv`` API.

    The constructor takes ``num_envs``, ``config`` and the other fields of
    :class:`rogue_gym.settings.PoolSettings` as keywords, plus ``render_mode`` (``None``,
    ``"ansi"`` or ``"rgb_array"``).

    * Same-step autoreset: when an episode ends, ``step_wait`` returns the next episode's first
      observation, with ``infos[i]["terminal_observation"]`` (the last observation, a copy) and
      ``infos[i]["TimeLimit.truncated"] = truncated and not terminated``. ``infos[i]["episode"]``
      = ``{"r": return, "l": length, "t": seconds since creation}`` as SB3's ``Monitor`` writes it.
    * A restarted worker's envs end their episode as truncated (``TimeLimit.truncated=True``,
      ``infos[i]["worker_restarted"]=True``, ``terminal_observation`` = last good observation).
    * ``seed(s)`` applies at the next ``reset()``: env ``i``'s episodes follow the schedule of base
      seed ``s`` (SB3's ``s + i`` convention is replaced by the pool's per-env schedule).

    **Array lifetimes.** The observation array returned by ``reset``/``step_wait`` is a view of
    one of the pool's two shared-memory batch slots, written by the workers alternately: it
    stays intact until the second following call, which is what SB3's rollout collection needs
    (it keeps the previous observation while stepping). Copy it if you keep observations
    longer. Rewards, dones and infos are fresh.
    """

    def __init__(
        self,
        num_envs: int = PoolSettings.num_envs,
        config: ConfigLike = PoolSettings.config,
        *,
        render_mode: Optional[str] = None,
        **options: Any,
    ) -> None:
        if render_mode not in (None, "ansi", "rgb_array"):
            raise ValueError(
                f"render_mode must be None, 'ansi' or 'rgb_array', got {render_mode!r}"
            )
        self._render_mode = render_mode
        settings = PoolSettings.from_kwargs({"num_envs": num_envs, "config": config, **options})
        self._core = PoolCore(settings, same_step=True)
        super().__init__(
            self._core.num_envs, self._core.single_observation_space, spaces.Discrete(len(ACTIONS))
        )
        self._history = ActionHistory(self._core) if render_mode is not None else None
        self._actions: Optional[np.ndarray] = None
        self._last_obs: Optional[np.ndarray] = None
        self._started = False
        self._t0 = time.perf_counter()

    # ------------------------------------------------------------------------------------
    def reset(self) -> np.ndarray:
        """Reset every env (using the seed given to :meth:`seed`, if any) and return the obs."""
        seed = self._seeds[0] if self._seeds and self._seeds[0] is not None else None
        obs, recs = self._core.reset(seed)
        self.reset_infos = [self._core.info_dict(recs, i) for i in range(self.num_envs)]
        if self._history is not None:
            self._history.on_reset(recs, np.ones(self.num_envs, bool))
        self._reset_seeds()
        self._reset_options()
        self._last_obs = obs
        self._started = True
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        """Check and store the actions (one int per env) for :meth:`step_wait`."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        self._actions = self._core.validate_actions(actions).copy()

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        """Step every env; returns ``(obs, rewards, dones, infos)``."""
        if self._actions is None:
            raise RuntimeError("step_wait() called without step_async()")
        actions, self._actions = self._actions, None
        prev_obs = self._last_obs
        obs, recs = self._core.step(actions)
        terminated, truncated, restarted, has_final = PoolCore.flags(recs)
        dones = terminated | truncated
        rewards = recs["reward"].astype(np.float32)
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        final = self._core.final_obs
        now = round(time.perf_counter() - self._t0, 6)
        for i in np.flatnonzero(dones):
            info = infos[i]
            info.update(self._core.info_dict(recs, int(i)))
            if has_final[i] and final is not None:
                info["terminal_observation"] = final[i].copy()
            elif prev_obs is not None:
                info["terminal_observation"] = prev_obs[i].copy()
            info["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            info["episode"] = {
                "r": float(recs["episode_return"][i]),
                "l": int(recs["episode_length"][i]),
                "t": now,
            }
            if restarted[i]:
                info["worker_restarted"] = True
        if self._history is not None:
            self._history.on_step(actions, ~restarted, recs)
            self._history.on_reset(recs, dones, seed_known=False)
        self._last_obs = obs
        return obs, rewards, dones, infos

    def close(self) -> None:
        """Stop all workers and remove the pool's shared-memory files (idempotent)."""
        self._core.close()

    def __del__(self) -> None:
        core = getattr(self, "_core", None)
        if core is not None:
            core.close()

    # ------------------------------------------------------------------------------------
    def _screens(self, indices: Iterable[int]) -> list[str]:
        if self._history is None:
            raise RuntimeError("rendering needs render_mode='ansi' or 'rgb_array'")
        return [self._history.screen(i) for i in indices]

    def get_images(self) -> Sequence[Optional[np.ndarray]]:
        """One RGB image per env (one pixel per screen cell, coloured by glyph)."""
        if self._history is None:
            return [None] * self.num_envs
        return [screen_to_rgb(s) for s in self._screens(range(self.num_envs))]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """Read an attribute of the envs (``render_mode``, ``config``, ``max_steps``,
        ``stair_reward``, ``observation_space``, ``action_space``, ``episode_seed``,
        ``worker_pid``)."""
        idx = list(self._get_indices(indices))
        core = getattr(self, "_core", None)
        if attr_name == "render_mode":
            return [self._render_mode for _ in idx]
        if core is None:
            raise AttributeError(attr_name)
        if attr_name == "episode_seed":
            recs = core._recs[core._slot]
            return [int(recs["seed"][i]) for i in idx]
        values = {
            "config": core.config,
            "max_steps": core.max_steps,
            "stair_reward": core.stair_reward,
            "observation_space": self.observation_space,
            "action_space": self.action_space,
        }
        if attr_name == "worker_pid":
            pids = core.worker_pids
            epw = core.num_envs // core.num_workers
            return [pids[i // epw] for i in idx]
        if attr_name not in values:
            raise AttributeError(
                f"the envs have no attribute {attr_name!r} readable from Python (they run in workers)"
            )
        return [values[attr_name] for _ in idx]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Not supported: the envs run in worker processes (configure them at construction)."""
        raise AttributeError(f"cannot set {attr_name!r}: the envs run in worker processes")

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        """Call a method on the envs; supported: ``render`` (screens as text) and ``get_wrapper_attr``."""
        idx = list(self._get_indices(indices))
        if method_name == "render":
            return list(self._screens(idx))
        if method_name == "get_wrapper_attr":
            return self.get_attr(method_args[0], idx)
        raise AttributeError(
            f"the envs have no method {method_name!r} callable from Python (they run in workers)"
        )

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        """The envs are not gymnasium envs: never wrapped."""
        return [False for _ in self._get_indices(indices)]
