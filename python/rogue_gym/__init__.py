"""Rogue-Gym: a roguelike benchmark for generalization in reinforcement learning.

Three entry points:

* :class:`rogue_gym.envs.RogueEnv`: one game as a gymnasium ``Env`` (the original API).
* :func:`rogue_gym.make_vec` / :class:`rogue_gym.vector.RogueVectorEnv`: many games stepped by
  worker processes over shared memory, as a ``gymnasium.vector.VectorEnv``.
* :class:`rogue_gym.PoolVectorEnv`: any gymnasium env hosted in the same worker processes (a
  drop-in for ``AsyncVectorEnv``; ``make_vec("CartPole-v1", 64)`` builds one).
* :class:`rogue_gym.sb3.RogueVecEnv`: the same pool as a Stable-Baselines3 ``VecEnv``
  (imported lazily: ``import rogue_gym`` needs neither SB3 nor torch).

``RogueGym-v0`` is registered with gymnasium on import.
"""

from __future__ import annotations

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
    # SB3 (and torch) load only when the SB3 facade is asked for.
    if name in ("RogueVecEnv", "PoolVecEnv"):
        from . import sb3

        return getattr(sb3, name)
    if name == "tune":  # the module, callable as tune(env, num_envs) (python -m rogue_gym.tune)
        import importlib

        return importlib.import_module(".tune", __name__)
    if name == "sb3":
        from . import sb3

        return sb3
    raise AttributeError(f"module 'rogue_gym' has no attribute {name!r}")
