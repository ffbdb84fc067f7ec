"""The RLlib recipe: every EnvRunner steps its envs through one pool.

RLlib's new API stack builds each EnvRunner's envs with ``gymnasium.make_vec``. With
``gym_env_vectorize_mode="vector_entry_point"`` and the env given as :func:`make_rllib_env`
(registered with Ray as ``"rogue_gym_pool"``), that call builds a pool (``rogue_gym.make_vec``) in the EnvRunner's process: its worker processes
step the envs and the runner reads their observations from shared memory. Within a node the
pool restarts a dead worker itself; a lost EnvRunner is RLlib's to restart
(``config.fault_tolerance``; see ``docs/ray.md``).
"""

from __future__ import annotations

from typing import Any, Optional, Union

import gymnasium as gym

from ..registration import ENV_ID

__all__ = ["configure_rllib", "make_rllib_env"]

#: The env_config key naming the env (a gymnasium id) :func:`make_rllib_env` builds.
ENV_KEY = "env"
#: The name :func:`make_rllib_env` is registered under in Ray's env registry.
RLLIB_ENV_NAME = "rogue_gym_pool"


def make_rllib_env(env_config: dict[str, Any]) -> Union[gym.Env, gym.vector.VectorEnv]:
    """RLlib's env creator: a pool of ``env_config["num_envs"]`` envs (the vector entry point),
    or one plain env when RLlib asks without ``num_envs``.

    ``env_config[ENV_KEY]`` is ``"RogueGym-v0"`` (the native game) or any registered gymnasium
    id (hosted as Python envs); every other key is a pool option of ``rogue_gym.make_vec`` (or,
    for a single env, a keyword of ``gymnasium.make`` under ``env_kwargs``).
    """
    from ..vector import make_vec

    options = dict(env_config)
    env = options.pop(ENV_KEY, ENV_ID)
    num_envs = options.pop("num_envs", None)
    if num_envs is None:
        if env == ENV_ID:
            return gym.make(ENV_ID)
        return gym.make(env, **dict(options.get("env_kwargs") or {}))
    return make_vec(env, int(num_envs), **options)


def configure_rllib(
    config: Any,
    env: str = ENV_ID,
    *,
    num_env_runners: int = 1,
    num_envs_per_env_runner: int = 8,
    num_cpus_per_env_runner: Optional[float] = None,
    variant: Optional[str] = "small",
    **pool_kwargs: Any,
) -> Any:
    """Fill ``config.environment``, ``config.env_runners`` and the RL module so that RLlib
    steps ``env`` through one pool per EnvRunner; returns ``config``.

    Args:
        config: an ``AlgorithmConfig`` of the new API stack (e.g. ``PPOConfig()``).
        env: ``"RogueGym-v0"`` or any registered gymnasium id.
        num_env_runners: EnvRunner actors (0: sample in the driver).
        num_envs_per_env_runner: envs of each runner's pool.
        num_cpus_per_env_runner: CPUs Ray reserves per runner; default the pool's
            ``num_workers`` (default 1 here) plus one for the runner itself.
        variant: for ``RogueGym-v0``, the paper's network RLlib uses
            (:class:`rogue_gym.ray.module.RogueRLModule`, ``"small"`` by default); ``None``
            leaves the RL module to the caller. Ignored for other envs.
        **pool_kwargs: pool options (``rogue_gym.make_vec``: ``num_workers``, ``obs``,
            ``config``, ...). ``copy=True`` and ``autoreset_mode="NEXT_STEP"`` are set for you:
            RLlib keeps the arrays it is handed and assumes next-step autoreset.

    ``seed`` is not a pool option here: RLlib seeds each runner's pool at its first reset with
    ``config.debugging(seed=...)`` plus the runner's index, so pass it there.
    """
    if "seed" in pool_kwargs:
        raise TypeError(
            "configure_rllib: pass the seed to config.debugging(seed=...); RLlib seeds each "
            "EnvRunner's pool with it plus the runner's index"
        )
    for key, needed in (("copy", True), ("autoreset_mode", "NEXT_STEP")):
        if key in pool_kwargs and str(pool_kwargs[key]).upper() != str(needed).upper():
            raise ValueError(f"configure_rllib: RLlib needs {key}={needed!r}")
    num_workers = int(pool_kwargs.setdefault("num_workers", 1))
    pool_kwargs["copy"] = True
    pool_kwargs["autoreset_mode"] = "NEXT_STEP"
    if num_cpus_per_env_runner is None:
        num_cpus_per_env_runner = num_workers + 1
    from ray.tune.registry import register_env

    register_env(RLLIB_ENV_NAME, make_rllib_env)
    config = config.environment(RLLIB_ENV_NAME, env_config={ENV_KEY: env, **pool_kwargs})
    config = config.env_runners(
        num_env_runners=num_env_runners,
        num_envs_per_env_runner=num_envs_per_env_runner,
        num_cpus_per_env_runner=num_cpus_per_env_runner,
        gym_env_vectorize_mode="vector_entry_point",
    )
    if env == ENV_ID and variant is not None:
        from ray.rllib.core.rl_module.rl_module import RLModuleSpec

        from .module import RLLIB_VARIANTS, RogueRLModule

        if variant not in RLLIB_VARIANTS:
            raise ValueError(f"variant must be one of {RLLIB_VARIANTS} or None, got {variant!r}")
        config = config.rl_module(
            rl_module_spec=RLModuleSpec(
                module_class=RogueRLModule, model_config={"variant": variant}
            )
        )
    return config
