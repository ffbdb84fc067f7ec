"""Hosting any gymnasium env in the pool's worker processes: the parts that are not the vector
env class itself (that is :class:`rogue_gym.PoolVectorEnv`, over the hosted env kind
:mod:`rogue_gym.kinds.hosted`).

* :mod:`~rogue_gym.hosted.layout`: how a space is laid out as flat bytes in shared memory.
* :mod:`~rogue_gym.hosted.adapter`: the worker side, which builds and calls each env.
* :mod:`~rogue_gym.hosted.infos`: infos as typed rows or pickles.
* :mod:`~rogue_gym.hosted.leases`: observations handed out without a copy.
"""

from typing import Any

from .layout import SpaceLayout, UnsupportedSpaceError

__all__ = ["PoolVectorEnv", "SpaceLayout", "UnsupportedSpaceError"]


def __getattr__(name: str) -> Any:
    if name == "PoolVectorEnv":  # rogue_gym.hosted.PoolVectorEnv, its name of old
        from ..vector import PoolVectorEnv

        return PoolVectorEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
