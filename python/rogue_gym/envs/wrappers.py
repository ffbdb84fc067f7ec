"""The original reward wrappers: ``StairRewardEnv`` and ``FirstFloorEnv``."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from .rogue_env import RogueEnv

__all__ = ["FirstFloorEnv", "StairRewardEnv"]


class StairRewardEnv(gym.Wrapper):
    """Adds ``stair_reward`` the first time each new (deeper) floor is reached.

    Original semantics: the bonus is paid once per step call in which the dungeon level rose
    above the deepest level seen in this episode. It stacks with the inner env's own
    ``stair_reward`` (0 by default in :class:`RogueEnv`).
    """

    def __init__(self, env: gym.Env, stair_reward: float = 50.0) -> None:
        if not isinstance(env.unwrapped, RogueEnv):
            raise TypeError(
                f"StairRewardEnv needs a RogueEnv inside, got {type(env.unwrapped).__name__}"
            )
        super().__init__(env)
        self.stair_reward = float(stair_reward)
        self.current_level = 1

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset the inner env and the deepest-level counter."""
        obs, info = self.env.reset(**kwargs)
        self.current_level = 1
        return obs, info

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Step and add the bonus when a new deepest level was reached."""
        obs, raw_reward, terminated, truncated, info = self.env.step(action)
        reward = float(raw_reward)
        level = int(self.env.get_wrapper_attr("status")["dungeon_level"])
        if level > self.current_level:
            reward += self.stair_reward
            self.current_level = level
        return obs, reward, terminated, truncated, info


class FirstFloorEnv(StairRewardEnv):
    """Like :class:`StairRewardEnv`, but the episode ends (``terminated``) after the first descent."""

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Step; ``terminated`` becomes ``True`` once floor 2 is reached."""
        obs, reward, terminated, truncated, info = super().step(action)
        if self.current_level >= 2:
            terminated = True
            self.env.set_wrapper_attr("_needs_reset", True)
        return obs, reward, terminated, truncated, info

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset the inner env (``seed=``, ``options=``)."""
        return super().reset(**kwargs)
