"""The one front end: a gymnasium ``VectorEnv`` and an SB3 ``VecEnv`` over one core, for every
env kind.

* :class:`rogue_gym.front.vector_env.FrontVectorEnv`: gymnasium's API (reset with seeds, options
  and ``reset_mask``, the three autoreset modes, the split async API, EnvPool-style send/recv,
  call/get_attr/set_attr, render, close);
* :class:`rogue_gym.front.vec_env.FrontVecEnv`: SB3's ``VecEnv`` over it (needs
  stable-baselines3);
* :class:`rogue_gym.front.core.Core`: the native pool, its batch slots and buffers.

The env kind (:mod:`rogue_gym.kinds`) is bound once at construction. The public classes
(``RogueVectorEnv``, ``PoolVectorEnv``, ``RogueVecEnv``, ``PoolVecEnv``) are these classes with
the constructor of their kind.
"""

from __future__ import annotations
