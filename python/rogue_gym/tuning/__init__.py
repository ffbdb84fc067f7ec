"""Let the pool choose its layout: time the candidate layouts of one env side by side and print
the best keyword arguments.

Command line::

    python -m rogue_gym.tuning CartPole-v1 [--num-envs 64] [--seconds 2] [--rounds 3]
    python -m rogue_gym.tuning my_pkg.envs:make_env --num-envs 256
    python -m rogue_gym.tuning RogueGym-v0        # the native game (paper config)

From Python: ``rogue_gym.tune(env, num_envs=64)`` (this package's :func:`tune`) with a
gymnasium id, an env factory (a callable, or ``"module:callable"``), a list of ``env_fns`` (one
per env), or ``"RogueGym-v0"``; it returns a :class:`TuneResult`. A factory of PettingZoo envs
is tuned as rows (:meth:`rogue_gym.PoolVectorEnv.from_pettingzoo`: ``num_envs`` envs, every
worker count up to it, views or copies, against a loop over the envs in this process).

The candidates: ``num_workers`` from 1 to twice the CPU count; observations lent (``copy=True``)
or as shared-memory views (``copy=False``), and where the batch is large enough to be lent, lent
from three batch slots (``batch_slots=3``: every batch lent, one more batch of ``/dev/shm``);
the EnvPool-style async loop (``send``/``recv``) with ``batch_size`` = one worker's envs and half the envs, and with one worker per env (up
to :data:`MAX_ONE_PER_ENV` envs); TorchRL's deadline harvest (``harvest``: ``recv(min_batch=1,
max_batch=num_envs, timeout=1e-3)``, every env received sent at once), which serves envs of
uneven speed (slow resets) best; and for a
gymnasium id with its own vector entry point, one such vector env per worker
(:meth:`rogue_gym.PoolVectorEnv.from_vector_env`). ``SyncVectorEnv`` in this process is timed
too: where it is faster, tune says so and recommends it. Each candidate runs in a fresh pool
for ``seconds`` of random actions after a warm-up, every candidate in the first round, then
those within half of the best (the others are out of the running, and out of the time) in the
rounds after, in a new order each round; then the leaders (up to four, within 10% of the best)
as many rounds again.
Last, the fastest meets each of the next four within 25% in a duel (:func:`duel`): both pools
alive, stepped in ``8 * rounds`` pairs of alternating bursts of ``seconds / 8``, whose median
ratio decides; the winner stays on. Runs minutes apart see a shared machine at different
speeds, by more than the gap between close layouts; bursts a fraction of a second apart do
not. The table gives each one's median steps/s, its ``stats()`` breakdown and the duels.
The whole run is bounded: tune times one start-up of the envs (an env slow to build makes
every candidate slow to start, and gets a start-up bound to match), says how long it will take,
and starts no new run once that time and half again have passed.
"""

from __future__ import annotations

from .candidates import Candidate, candidates
from .duel import Duel, duel
from .report import TuneResult
from .search import tune
from .timing import Timing

__all__ = ["Candidate", "Duel", "Timing", "TuneResult", "candidates", "duel", "tune"]
