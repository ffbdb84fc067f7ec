"""Env kinds: what differs between the envs a pool can host, as data and a few callables.

A kind (:class:`rogue_gym.kinds.spec.Kind`) is bound once when a vector env is built; the
facades of :mod:`rogue_gym.front` own every call and do everything else, once, for every kind.
A new kind is one module here implementing the spec (see :mod:`rogue_gym.kinds.spec`).

* :class:`rogue_gym.kinds.native.NativeKind`: Rogue-Gym's own game, run by the workers in Rust
  (spaces, seed schedule, infos and render come from the engine).
* :class:`rogue_gym.kinds.hosted.HostedKind`: gymnasium envs hosted in the workers (``env_fns``,
  or one vector env per worker).
"""

from __future__ import annotations
