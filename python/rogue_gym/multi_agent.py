"""PettingZoo envs in the pool: every (env, agent) pair is one row of a gymnasium vector env.

:class:`AgentRows` turns ``k`` PettingZoo ``ParallelEnv`` s (AEC envs go through PettingZoo's
own ``aec_to_parallel``) of ``A`` agents each into one ``VectorEnv`` of ``k * A`` rows: row
``e * A + j`` is env ``e``'s agent ``possible_agents[j]``. That is parameter sharing, as
SuperSuit's vector envs give it. The pool hosts one :class:`AgentRows` per worker block
(:meth:`rogue_gym.PoolVectorEnv.from_pettingzoo`), the block made of whole envs, so every
promise of the pool holds per env: zero-copy rows, seeds independent of the layout, a crashed
worker costing its envs one truncated episode.

Rows whose agent is absent (dead, or not yet there):

* ``infos["active"]`` is ``False`` for them (``True`` for a row whose agent acted at this call,
  or is present after a reset);
* their action is ignored, their observation is zeros, their reward 0 and their flags ``False``;
* a row reports ``terminated``/``truncated`` once, at the step its agent is done; the env's
  episode ends when all its agents are done, and the env then autoresets as a whole, in the
  vector env's autoreset mode (``NEXT_STEP``: at its next step; ``SAME_STEP``: at once, with
  each ended row's ``final_obs`` and ``final_info``).

Every agent must have the same observation and action space (pad them to one first, e.g. with
SuperSuit's ``pad_observations_v0``/``pad_action_space_v0``); spaces of fixed-size arrays
(``Box``, ``Discrete``, ``MultiDiscrete``, ``MultiBinary``). ``reset(seed=s)`` seeds env ``e``
with ``s + e``, as SuperSuit's ``concat_vec_envs`` does (a seed list: its first row's entry).

This module is the caller's side (:meth:`rogue_gym.PoolVectorEnv.from_pettingzoo` builds on
it); :class:`AgentRows` itself runs in the workers and lives in
:mod:`rogue_gym.worker.agent_rows`.
"""

from __future__ import annotations

import functools
from typing import Any, Callable

from gymnasium.vector import AutoresetMode

from . import _native
from .worker.agent_rows import AgentRows, block_rows, parallel

__all__ = ["AgentRows", "agent_rows_fn", "hosted_rows", "num_agents"]


def num_agents(env_fn: Callable[[], Any]) -> int:
    """How many agents (rows) one env of ``env_fn`` has: ``len(possible_agents)``."""
    env = parallel(env_fn())
    try:
        return len(env.possible_agents)
    finally:
        env.close()


def agent_rows_fn(
    env_fn: Callable[[], Any], agents: int, autoreset_mode: AutoresetMode
) -> Callable[[int], AgentRows]:
    """The ``vector_env_fn`` of a pool block: ``fn(rows)`` builds :class:`AgentRows` of
    ``rows // agents`` envs of ``env_fn`` (picklable for the workers, which import only
    :mod:`rogue_gym.worker.agent_rows` for it)."""
    return functools.partial(block_rows, env_fn, agents, AutoresetMode(autoreset_mode).value)


def hosted_rows(
    env_fn: Callable[[], Any], num_envs: int, autoreset_mode: Any, options: dict[str, Any]
) -> tuple[Any, dict[str, Any]]:
    """What :meth:`rogue_gym.PoolVectorEnv.from_pettingzoo` hosts: the vector-env function of
    ``num_envs`` envs of ``env_fn`` (one row per agent, whole envs per worker) and the pool
    options, ``num_workers`` resolved against the envs (not the rows)."""

    from .kinds.hosted import VectorEnvFn

    if int(num_envs) < 1:
        raise ValueError(f"num_envs must be at least 1, got {num_envs}")
    workers = options.get("num_workers")
    if workers is None:
        workers = min(int(num_envs), _native.usable_cores())
    if not 1 <= int(workers) <= int(num_envs):
        raise ValueError(
            f"num_workers must be between 1 and num_envs ({num_envs}): each worker hosts whole "
            f"envs, all agents of an env on one worker; got {workers}"
        )
    agents = num_agents(env_fn)
    fn = agent_rows_fn(env_fn, agents, AutoresetMode(autoreset_mode))
    return VectorEnvFn(fn, int(num_envs) * agents, unit=agents), {
        **options,
        "num_workers": int(workers),
    }
