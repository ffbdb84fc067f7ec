"""Hosting any gymnasium env in the pool's worker processes.

* :class:`PoolVectorEnv`: a gymnasium ``VectorEnv`` over ``env_fns`` (a drop-in for
  ``AsyncVectorEnv``), in :mod:`~rogue_gym.hosted.vector_env`.
* :mod:`~rogue_gym.hosted.layout`: how a space is laid out as flat bytes in shared memory.
* :mod:`~rogue_gym.hosted.adapter`: the worker side, which builds and calls each env.
"""

from .layout import SpaceLayout, UnsupportedSpaceError
from .vector_env import PoolVectorEnv

__all__ = ["PoolVectorEnv", "SpaceLayout", "UnsupportedSpaceError"]
