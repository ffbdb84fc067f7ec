"""The pool as a Stable-Baselines3 ``VecEnv`` (needs ``stable-baselines3``): thin names over
:class:`rogue_gym.front.vec_env.FrontVecEnv` with the constructor of their env kind.

* :class:`RogueVecEnv`: the native game.
* :class:`PoolVecEnv`: any gymnasium env (a drop-in for ``SubprocVecEnv``).

Import them explicitly (``from rogue_gym.sb3 import RogueVecEnv``): ``import rogue_gym`` does
not import SB3 or torch.
"""

from __future__ import annotations

import multiprocessing
from typing import Any, Callable, Optional, Sequence

import gymnasium as gym
from gymnasium.vector import AutoresetMode

from ._config import ConfigLike
from .front.vec_env import FrontVecEnv
from .kinds.hosted import VectorEnvFn
from .settings import PoolSettings
from .vector import PoolVectorEnv, RogueVectorEnv

__all__ = ["PoolVecEnv", "RogueVecEnv"]


class RogueVecEnv(FrontVecEnv):
    """``num_envs`` Rogue-Gym games in worker processes, with SB3's ``VecEnv`` API (see
    :class:`rogue_gym.front.vec_env.FrontVecEnv` for the step contract).

    The constructor takes ``num_envs``, ``config`` and the other fields of
    :class:`rogue_gym.settings.PoolSettings` as keywords, plus ``render_mode`` (``None``,
    ``"ansi"``, ``"human"`` or ``"rgb_array"``) and ``copy``. ``seed(s)`` applies at the next
    ``reset()``: env ``i``'s episodes follow the schedule of base seed ``s`` (SB3's ``s + i``
    convention is the pool's per-env schedule).

    **Array lifetimes.** With ``copy=False`` (the default) the observation array returned by
    ``reset``/``step_wait`` is a view of one of the pool's shared-memory batch slots: it stays
    intact until the second following call, which is what SB3's rollout collection needs (it
    keeps the previous observation while stepping). Rewards, dones and infos are fresh.
    """

    def __init__(
        self,
        num_envs: int = PoolSettings.num_envs,
        config: ConfigLike = PoolSettings.config,
        *,
        render_mode: Optional[str] = None,
        copy: bool = False,
        **options: Any,
    ) -> None:
        super().__init__(
            RogueVectorEnv(
                num_envs,
                config,
                autoreset_mode=AutoresetMode.SAME_STEP,
                render_mode=render_mode,
                copy=copy,
                **options,
            )
        )


class PoolVecEnv(FrontVecEnv):
    """``len(env_fns)`` gymnasium envs in worker processes, as an SB3 ``VecEnv`` (a drop-in for
    ``SubprocVecEnv``: ``make_vec_env(..., vec_env_cls=PoolVecEnv)`` works).

    Args:
        env_fns: one callable per env (cloudpickled).
        start_method: accepted for ``SubprocVecEnv`` compatibility; workers are always fresh
            processes (``python -m rogue_gym.worker``), never forks.
        **options: keywords of :class:`rogue_gym.PoolVectorEnv` (``num_workers``,
            ``on_worker_failure``, ``step_timeout``, ``max_restarts``, ``info_bytes``, ...).

    **Array lifetimes.** Observations are the caller's to keep (``copy=True``, the default);
    rewards, dones and infos are fresh.
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
        super().__init__(PoolVectorEnv(env_fns, **options))

    @classmethod
    def from_vector_env(
        cls, vector_env_fn: Callable[[int], gym.vector.VectorEnv], num_envs: int, **options: Any
    ) -> PoolVecEnv:
        """``num_envs`` envs hosted as one gymnasium vector env per worker block (see
        :meth:`rogue_gym.PoolVectorEnv.from_vector_env`), as an SB3 ``VecEnv``. The vector env
        must autoreset ``SAME_STEP``, SB3's convention, e.g. ``lambda n: AtariVectorEnv("pong",
        num_envs=n, num_threads=1, autoreset_mode="SameStep")``. ``set_attr`` is not
        available; reset options reach every env of the block."""
        return cls(VectorEnvFn(vector_env_fn, int(num_envs)), **options)  # type: ignore[arg-type]

    @classmethod
    def from_pettingzoo(
        cls, env_fn: Callable[[], Any], num_envs: int, **options: Any
    ) -> PoolVecEnv:
        """``num_envs`` PettingZoo envs with one row per (env, agent) (see
        :meth:`rogue_gym.PoolVectorEnv.from_pettingzoo`), as an SB3 ``VecEnv``: parameter
        sharing, as SuperSuit's ``concat_vec_envs_v1`` gives it. Each env autoresets as a whole
        (SAME_STEP); a row whose agent is absent has ``active`` False in its info."""
        from .multi_agent import hosted_rows

        rows, options = hosted_rows(env_fn, num_envs, AutoresetMode.SAME_STEP, options)
        return cls(rows, **options)
