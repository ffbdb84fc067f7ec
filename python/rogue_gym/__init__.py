"""Rogue-Gym: a roguelike benchmark for generalization in reinforcement learning.

The entry points:

* :class:`rogue_gym.envs.RogueEnv`: one game as a gymnasium ``Env`` (the original API).
* :func:`rogue_gym.make_vec` / :class:`rogue_gym.vector.RogueVectorEnv`: many games stepped by
  worker processes over shared memory, as a ``gymnasium.vector.VectorEnv``.
* :class:`rogue_gym.PoolVectorEnv`: any gymnasium env hosted in the same worker processes (a
  drop-in for ``AsyncVectorEnv``; ``make_vec("CartPole-v1", 64)`` builds one).
* :class:`rogue_gym.sb3.RogueVecEnv` / :class:`rogue_gym.sb3.PoolVecEnv`: the same pools as
  Stable-Baselines3 ``VecEnv`` s (imported lazily: ``import rogue_gym`` needs neither SB3 nor
  torch).
* :mod:`rogue_gym.envpool`: EnvPool's API (``envpool.make``) over any gymnasium id.
* :func:`rogue_gym.tune`: time the pool's layouts for an env and say which is fastest
  (:mod:`rogue_gym.tuning`).

``RogueGym-v0`` is registered with gymnasium on import.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ._native import __version__  # the workspace version (Cargo.toml), written once
from .registration import ENV_ID, register_envs

if TYPE_CHECKING:  # the lazy names below, for type checkers
    from . import envs
    from ._config import PAPER_CONFIG
    from .envs import (
        ACTIONS,
        DungeonType,
        FirstFloorEnv,
        ImageSetting,
        RogueEnv,
        StairRewardEnv,
        StatusFlag,
    )
    from .errors import CorruptInfoError, EnvFailedError, PoolClosedError, WorkerCrashedError
    from .sb3 import PoolVecEnv, RogueVecEnv
    from .tuning import tune
    from .vector import PoolVectorEnv, RogueVectorEnv, make_vec

__all__ = [
    "ACTIONS",
    "ENV_ID",
    "PAPER_CONFIG",
    "CorruptInfoError",
    "DungeonType",
    "EnvFailedError",
    "FirstFloorEnv",
    "ImageSetting",
    "PoolClosedError",
    "PoolVecEnv",
    "PoolVectorEnv",
    "RogueEnv",
    "RogueVecEnv",
    "RogueVectorEnv",
    "StairRewardEnv",
    "StatusFlag",
    "WorkerCrashedError",
    "__version__",
    "envs",
    "make_vec",
    "tune",
]

register_envs()

#: Where each public name lives. They load on first use, so that a pool's worker process
#: (``python -m rogue_gym.worker``, which runs this file first) loads none of the caller's
#: side (the front, the kinds, the facades), and SB3 and torch load only with the SB3 facade.
_LAZY = {
    "envs": ("envs", None),
    "PAPER_CONFIG": ("_config", "PAPER_CONFIG"),
    **{
        name: ("envs", name)
        for name in (
            "ACTIONS",
            "DungeonType",
            "FirstFloorEnv",
            "ImageSetting",
            "RogueEnv",
            "StairRewardEnv",
            "StatusFlag",
        )
    },
    **{
        name: ("errors", name)
        for name in ("CorruptInfoError", "EnvFailedError", "PoolClosedError", "WorkerCrashedError")
    },
    **{name: ("vector", name) for name in ("PoolVectorEnv", "RogueVectorEnv", "make_vec")},
    "RogueVecEnv": ("sb3", "RogueVecEnv"),
    "PoolVecEnv": ("sb3", "PoolVecEnv"),
    "sb3": ("sb3", None),
    "tune": ("tuning", "tune"),  # rogue_gym.tune(env, num_envs) is rogue_gym.tuning.tune
}


def __getattr__(name: str) -> Any:
    # import_module, not ``from . import x``: that would ask this function again, without end.
    where = _LAZY.get(name)
    if where is None:
        raise AttributeError(f"module 'rogue_gym' has no attribute {name!r}")
    module = importlib.import_module(f".{where[0]}", __name__)
    value = module if where[1] is None else getattr(module, where[1])
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
