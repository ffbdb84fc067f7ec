"""What an env kind is: the :class:`Kind` spec the front binds once per vector env.

A kind says what differs between the envs a pool can host, and nothing more: its spaces and
facts, the native pool's settings, its seeds, how actions and observations are coded in
shared memory, how a call's columns and extra info become infos, which env operations it
serves, and how it renders. The front (:mod:`rogue_gym.front`) owns every call and its
lifecycle (:class:`rogue_gym.kinds.view.CallState`) for every kind. A kind reads the pool only
through the view it is bound to (:class:`rogue_gym.kinds.view.PoolView`), and imports nothing
of the front.

The order of calls:

1. construction, then :meth:`Kind.pool_settings` once (the pool starts from it);
2. :meth:`Kind.bind` once, with the view, when the pool runs;
3. per call: :meth:`Kind.seeds` (resets), :meth:`Kind.actions` (steps and sends) before the
   pool call; after it :meth:`Kind.infos`, then ``facts.obs_filler`` (it may use what the
   infos brought), then :meth:`Kind.batch_views` where the front needs fresh views;
4. :meth:`Kind.run_ops` and :meth:`Kind.render` between calls, off the hot path.

A new kind is one module of this package implementing :class:`Kind`;
``tests/python/test_kind_spec.py`` builds a small one (the pool's built-in test env) to show
the least one needs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Optional, Protocol, Sequence, Union

import numpy as np
from gymnasium import spaces

from ..protocol.ops import Interpreter
from .result import Result
from .view import PoolView

#: The env ids of a batch of rows: an int64 array (as ``send`` passes them) or a sequence.
EnvIds = Union[np.ndarray, Sequence[int]]

#: ``(obs, env_ids) -> obs``: make a batch of observations (of every env, or of ``env_ids``)
#: whole after the call's infos were read (leaves of no fixed size travel apart).
ObsFiller = Callable[[Any, Optional[np.ndarray]], Any]

__all__ = ["EnvIds", "Kind", "KindFacts", "ObsFiller"]


@dataclass(frozen=True)
class KindFacts:
    """What the front and gymnasium need to know of a kind's envs, given once."""

    #: Envs in the pool.
    num_envs: int
    #: One env's spaces.
    single_observation_space: spaces.Space
    single_action_space: spaces.Space
    #: The envs' ``metadata`` (render modes), render mode and gymnasium ``EnvSpec`` (if any).
    metadata: dict[str, Any]
    render_mode: Optional[str]
    env_spec: Any
    #: Program and leading args of a worker process.
    worker_command: Sequence[str]
    #: Who serves the env operations (named in refusals), and the operations served
    #: (:data:`rogue_gym.protocol.ops.ENV_OPS`).
    who: Union[Interpreter, str]
    ops: frozenset[str]
    #: Longest episode the front logs for a replay (:attr:`rogue_gym.kinds.view.CallState.log`); ``None`` for a
    #: kind that does not render by replay.
    log_steps: Optional[int] = None
    #: ``None`` when the slot's observations are whole as the workers write them; else the
    #: function that makes them whole. Given once: a kind without it costs the hot path nothing.
    obs_filler: Optional[ObsFiller] = None
    #: Env info rows received so far as typed rows and as pickles (``stats()``); ``None``: the
    #: kind's infos are fixed columns, not rows.
    info_counts: Optional[Callable[[], tuple[int, int]]] = None


class Kind(Protocol):
    """An env kind, as data and a few callables. The step path calls :meth:`actions` and
    :meth:`infos` once per step, never anything per env."""

    @property
    def facts(self) -> KindFacts:
        """What the front and gymnasium need to know of the envs."""
        ...

    def pool_settings(self) -> dict[str, Any]:
        """The native pool's settings (JSON object) but the autoreset mode and slot count."""
        ...

    def bind(self, view: PoolView) -> None:
        """Called once the pool runs: the view to read it through from now on."""
        ...

    def batch_views(self, rows: np.ndarray) -> Any:
        """Observations of ``rows`` (``(k, obs_bytes)`` uint8) as a batch of the observation
        space, without a copy."""
        ...

    def actions(self, actions: Any, env_ids: Optional[EnvIds]) -> np.ndarray:
        """A batch of actions (for every env, or ``env_ids``) checked, as the pool takes them:
        int64 indices or uint8 bytes."""
        ...

    def seeds(self, seed: Any, mask: Optional[np.ndarray]) -> Optional[dict[str, Any]]:
        """``reset(seed=seed)``: the episode-seed schedule of a full reset (``mask`` is
        ``None``; ``None`` keeps the current one), or, for a partial reset of the envs of
        ``mask``, seed their next reset (an int ``s`` seeds env ``i`` with ``s + i``, a list
        gives each env's) and return ``None``. ``ValueError``/``TypeError`` for a seed the
        kind cannot take."""
        ...

    def infos(self, result: Result, only: Optional[np.ndarray]) -> dict[str, Any]:
        """The infos of a call's rows (``only``: a partial reset's mask; the other rows' info
        is empty), as gymnasium's vector envs return them, SAME_STEP's ``final_obs`` and
        ``final_info`` included (:func:`rogue_gym.kinds.final_obs.add_final_obs`). The front
        adds what every kind reports (``worker_restarted``, ``env_id``)."""
        ...

    def run_ops(
        self,
        op: str,
        name: str,
        arguments: Sequence[tuple[tuple[Any, ...], dict[str, Any]]],
        indices: Sequence[int],
    ) -> list[Any]:
        """Run env operation ``op`` (one of ``facts.ops``) on the envs ``indices`` with
        ``arguments[j]`` for the ``j``-th; one result each."""
        ...

    def render(self) -> Optional[tuple[Any, ...]]:
        """Every env's frame in the render mode."""
        ...
