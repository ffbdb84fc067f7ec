"""What a vector env built by ``vector_env_fn(n)`` must be for the pool to host it: checked on
the caller's side (a probe of one env) and in each worker (its block)."""

from __future__ import annotations

from typing import Any

from gymnasium.vector import AutoresetMode, VectorEnv

__all__ = ["check_vector_env"]


def check_vector_env(envs: Any, num_envs: int, autoreset_mode: Any) -> None:
    """Raise ``ValueError``/``TypeError`` unless ``envs`` is a gymnasium ``VectorEnv`` of
    ``num_envs`` envs that autoresets as the pool will (``autoreset_mode``)."""
    if not isinstance(envs, VectorEnv):
        raise TypeError(
            f"vector_env_fn({num_envs}) returned {type(envs).__name__!r}, not a gymnasium "
            "VectorEnv: it must build a vector env of that many envs"
        )
    if int(envs.num_envs) != num_envs:
        raise ValueError(
            f"vector_env_fn({num_envs}) built a vector env of {envs.num_envs} envs: it must "
            "build as many envs as it is asked for"
        )
    mode = envs.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
    if AutoresetMode(mode) != autoreset_mode:
        raise ValueError(
            f"the vector env autoresets {AutoresetMode(mode).name} but the pool "
            f"{autoreset_mode.name}: build it with the same autoreset mode"
        )
