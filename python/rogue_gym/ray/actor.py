"""``PoolActor``: one pool in a Ray actor, holding a contiguous slice of a larger set of envs.

The actor is the node's supervisor: its pool's worker processes step the envs and write the
observations into the node's shared memory, and the actor hands each batch to Ray, which
carries it to the driver. The actor knows which global envs it holds, so the seeds its envs
play are those of one big pool (the native game: the pool's ``shard`` option; hosted envs:
``reset(seed=s)`` seeds global env ``g`` with ``s + g``).
"""

from __future__ import annotations

import os
from typing import Any, Optional, Union

import numpy as np

from ..registration import ENV_ID

__all__ = ["PoolActor", "is_native"]

EnvLike = Union[str, Any]


def is_native(env: EnvLike) -> bool:
    """Whether ``env`` names Rogue-Gym's own game (run natively, not hosted)."""
    return isinstance(env, str) and env == ENV_ID


class PoolActor:
    """A pool of the global envs ``first_env .. first_env + num_envs - 1`` of ``total_envs``.

    Plain class; :class:`rogue_gym.ray.RayVectorEnv` runs it as a Ray actor. Every method
    returns plain numpy arrays and dicts (what Ray serializes without pickling the arrays).
    """

    def __init__(
        self, env: EnvLike, first_env: int, num_envs: int, total_envs: int, options: dict
    ) -> None:
        from ..vector import make_vec

        self.first_env = int(first_env)
        self.num_envs = int(num_envs)
        self.native = is_native(env)
        self.envs: Any
        if self.native:
            options = {**options, "shard": (self.first_env, int(total_envs))}
            self.envs = make_vec(self.num_envs, **options)
        else:
            self.envs = make_vec(env, self.num_envs, **options)

    def spaces(self) -> tuple[Any, Any]:
        """The single observation and action spaces."""
        return self.envs.single_observation_space, self.envs.single_action_space

    def pid(self) -> int:
        """The actor's process id."""
        return os.getpid()

    def reset(self, seed: Optional[int], options: Optional[dict]) -> tuple[np.ndarray, dict]:
        """Reset (every env, or ``options["reset_mask"]``'s), from global base seed ``seed``."""
        local_seed: Any = seed
        if seed is not None and not self.native:
            local_seed = [int(seed) + self.first_env + i for i in range(self.num_envs)]
        return self.envs.reset(seed=local_seed, options=options)

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """One step of every env of the actor."""
        return self.envs.step(actions)

    def call(self, name: str, args: tuple, kwargs: dict) -> tuple:
        """``call(name, *args, **kwargs)`` on every env of the actor."""
        return tuple(self.envs.call(name, *args, **kwargs))

    def close(self) -> None:
        """Close the pool (stops its workers, removes its shared-memory files)."""
        self.envs.close()
