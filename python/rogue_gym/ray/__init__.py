"""Rogue-Gym beyond one machine: pools under Ray (the optional extra ``rogue-gym[ray]``).

* :func:`configure_rllib`: RLlib's EnvRunners each step their envs through one pool
  (``RogueGym-v0`` or any gymnasium id), with the paper's Small network as the RL module
  (:class:`RogueRLModule`).
* :class:`RayVectorEnv`: for trainers that are not RLlib (``python -m rogue_gym.train``, SB3),
  a gymnasium vector env in the driver whose envs live in Ray actors, one pool per actor.
  Env indices and seeds are global: the same seed and ``num_envs`` play the same trajectories
  as one local pool, whatever the number of actors.

Zero-copy ends at the node boundary: inside an actor the pool's workers write observations
into shared memory; between the actor and the driver they travel through Ray's object store.
``docs/ray.md`` has the fault mapping and the scaling notes.
"""

from __future__ import annotations

from typing import Any

__all__ = ["RayVectorEnv", "RogueRLModule", "configure_rllib", "make_rllib_env"]


def __getattr__(name: str) -> Any:
    # Ray, and torch for the RL module, load only when asked for.
    if name in ("configure_rllib", "make_rllib_env"):
        from . import rllib

        return getattr(rllib, name)
    if name == "RogueRLModule":
        from .module import RogueRLModule

        return RogueRLModule
    if name == "RayVectorEnv":
        from .vector_env import RayVectorEnv

        return RayVectorEnv
    raise AttributeError(f"module 'rogue_gym.ray' has no attribute {name!r}")
