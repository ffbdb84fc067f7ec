"""The one pool factory for a suite: the native game with the suite's config, step limit and
stair reward, SAME_STEP autoreset. The trainer, the evaluator and the post-hoc scorer build
their pools here and add only what differs (seeds, seed policy, observation, failure policy,
batch size)."""

from __future__ import annotations

from typing import Any, Dict

from gymnasium.vector import AutoresetMode

from .suites import Suite

__all__ = ["obs_kwargs", "suite_pool"]


def obs_kwargs(obs: str) -> Dict[str, Any]:
    """``"symbol_onehot"`` or ``"symbol_onehot:float32"`` -> ``{"obs": ..., "dtype": ...}``."""
    name, _, dtype = obs.partition(":")
    return {"obs": name, "dtype": dtype or "uint8"}


def suite_pool(suite: Suite, num_envs: int, **options: Any) -> Any:
    """A :class:`rogue_gym.RogueVectorEnv` of ``num_envs`` games of ``suite`` (SAME_STEP);
    ``options`` are further :class:`rogue_gym.settings.PoolSettings` fields."""
    from .vector import RogueVectorEnv  # imported late: the suites work without the extension

    options.setdefault("autoreset_mode", AutoresetMode.SAME_STEP)
    return RogueVectorEnv(
        num_envs,
        config=suite.config,
        max_steps=suite.max_steps,
        stair_reward=suite.stair_reward,
        **options,
    )
