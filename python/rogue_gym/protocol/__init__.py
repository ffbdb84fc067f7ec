"""What the caller's side and the workers agree on, and nothing else: imported by both, it
imports neither.

* :mod:`~rogue_gym.protocol.ops`: the env operations (``call``, ``get_attr``, ``render``, ...)
  and the tables their interpreters declare.
* :mod:`~rogue_gym.protocol.exceptions`: an env's exception, encoded in a worker and rebuilt
  in the caller.
* :mod:`~rogue_gym.protocol.infos`: an env's info dict as typed rows or pickles.
* :mod:`~rogue_gym.protocol.layout`: a space laid out as flat bytes in shared memory.
* :mod:`~rogue_gym.protocol.registry`: the caller's gymnasium registry, carried to the workers.
* :mod:`~rogue_gym.protocol.vector_contract`: what a hosted vector env must be.
"""

from __future__ import annotations

from .layout import SpaceLayout, UnsupportedSpaceError

__all__ = ["NO_SEED", "SpaceLayout", "UnsupportedSpaceError"]

#: The seed the caller schedules to mean "reset without a seed" (no reseeding at all, as
#: gymnasium's vector envs do on a first ``reset()`` without one).
NO_SEED = 2**64 - 1
