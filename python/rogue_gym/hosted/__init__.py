"""Hosting any gymnasium env in the pool's worker processes: the parts that are not the vector
env class itself (that is :class:`rogue_gym.PoolVectorEnv`, over the hosted env kind
:mod:`rogue_gym.kinds.hosted`).

* :mod:`~rogue_gym.hosted.layout`: how a space is laid out as flat bytes in shared memory.
* :mod:`~rogue_gym.hosted.adapter`: the worker side, which builds and calls each env.
* :mod:`~rogue_gym.hosted.infos`: infos as typed rows or pickles.
* :mod:`~rogue_gym.hosted.leases`: observations handed out without a copy.
* :mod:`~rogue_gym.hosted.registry`: the caller's gymnasium registry, carried to the workers.
"""

from .layout import SpaceLayout, UnsupportedSpaceError

__all__ = ["SpaceLayout", "UnsupportedSpaceError"]
