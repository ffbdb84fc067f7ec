"""Registration with gymnasium: ``gymnasium.make("RogueGym-v0")`` and ``gymnasium.make_vec``."""

from __future__ import annotations

import gymnasium as gym

__all__ = ["ENV_ID", "register_envs"]

#: The gymnasium id of Rogue-Gym.
ENV_ID = "RogueGym-v0"


def register_envs() -> None:
    """Register ``RogueGym-v0`` (idempotent).

    ``gymnasium.make("RogueGym-v0", **kw)`` builds a :class:`rogue_gym.envs.RogueEnv`;
    ``gymnasium.make_vec("RogueGym-v0", num_envs=64, **kw)`` builds the pool
    (:class:`rogue_gym.vector.RogueVectorEnv`) through its ``vector_entry_point``.
    """
    if ENV_ID in gym.registry:
        return
    gym.register(
        id=ENV_ID,
        entry_point="rogue_gym.envs:RogueEnv",
        vector_entry_point="rogue_gym.vector:RogueVectorEnv",
        disable_env_checker=False,
    )
