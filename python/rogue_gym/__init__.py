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
from typing import Any

from . import envs
from ._config import PAPER_CONFIG
from ._native import __version__  # the workspace version (Cargo.toml), written once
from .envs import (
    ACTIONS,
    DungeonType,
    FirstFloorEnv,
    ImageSetting,
    RogueEnv,
    StairRewardEnv,
    StatusFlag,
)
from .errors import EnvFailedError, PoolClosedError, WorkerCrashedError
from .registration import ENV_ID, register_envs
from .vector import PoolVectorEnv, RogueVectorEnv, make_vec

__all__ = [
    "ACTIONS",
    "ENV_ID",
    "PAPER_CONFIG",
    "DungeonType",
    "EnvFailedError",
    "FirstFloorEnv",
    "ImageSetting",
    "PoolClosedError",
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


def __getattr__(name: str) -> Any:
    # SB3 (and torch) load only when the SB3 facade is asked for. import_module, not
    # ``from . import sb3``: that asks this function for ``sb3`` again, without end.
    if name in ("RogueVecEnv", "PoolVecEnv"):
        return getattr(importlib.import_module(".sb3", __name__), name)
    if name == "sb3":
        return importlib.import_module(".sb3", __name__)
    if name == "tune":  # rogue_gym.tune(env, num_envs) is rogue_gym.tuning.tune
        return importlib.import_module(".tuning", __name__).tune
    raise AttributeError(f"module 'rogue_gym' has no attribute {name!r}")
