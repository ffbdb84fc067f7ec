"""The one front end: a gymnasium ``VectorEnv`` and an SB3 ``VecEnv`` over one core, for every
env kind.

* :class:`rogue_gym.front.vector_env.FrontVectorEnv`: gymnasium's API (reset with seeds, options
  and ``reset_mask``, the three autoreset modes, the split async API, EnvPool-style send/recv,
  call/get_attr/set_attr, render, close);
* :class:`rogue_gym.front.vec_env.FrontVecEnv`: SB3's ``VecEnv`` over it (needs
  stable-baselines3);
* :class:`rogue_gym.front.core.Core`: the native pool, its batch slots and column buffers,
  one :class:`~rogue_gym.kinds.result.Result` per call, and the call lifecycle (a
  :class:`~rogue_gym.kinds.view.CallState`);
* :class:`rogue_gym.front.pool_view.CoreView`: the pool as the kind reads it;
* the rest of the caller's side: :mod:`~rogue_gym.front.worker_errors` (an env's exception
  raised as itself), :mod:`~rogue_gym.front.leases` (observations lent without a copy),
  :mod:`~rogue_gym.front.pending` (gymnasium's errors for split calls out of order),
  :mod:`~rogue_gym.front.reset_mask`, :mod:`~rogue_gym.front.sigterm` and
  :mod:`~rogue_gym.front.stats`.

The env kind (:mod:`rogue_gym.kinds`, a :class:`~rogue_gym.kinds.spec.Kind`) is bound once at
construction, to the view. The front imports the kinds' spec; the kinds import nothing of the
front. The public classes
(``RogueVectorEnv``, ``PoolVectorEnv``, ``RogueVecEnv``, ``PoolVecEnv``) are these classes with
the constructor of their kind.
"""

from __future__ import annotations
