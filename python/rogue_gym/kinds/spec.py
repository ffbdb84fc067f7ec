"""What an env kind is: the :class:`Kind` spec the front binds once per vector env.

A kind says what differs between the envs a pool can host, and nothing more: its spaces and
facts, the native pool's settings, its seeds, how actions and observations are coded in
shared memory, how a call's columns and extra info become infos, which env operations it
serves, and how it renders. The front (:mod:`rogue_gym.front`) owns every call and its
lifecycle (started, ended episodes, restarted workers, the episode log) for every kind.

A new kind is one module of this package implementing :class:`Kind`;
``tests/python/test_kind_spec.py`` builds a small one (the pool's built-in test env) to show
the least one needs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Optional, Protocol, Sequence, Union

import numpy as np
from gymnasium import spaces

from ..protocol.ops import Interpreter

if TYPE_CHECKING:
    from ..front.core import Core, Result

#: The env ids of a batch of rows: an int64 array (as ``send`` passes them) or a sequence.
EnvIds = Union[np.ndarray, Sequence[int]]

__all__ = ["EnvIds", "Kind", "KindFacts"]


@dataclass(frozen=True)
class KindFacts:
    """What the front and gymnasium need to know of a kind's envs, given once."""

    #: Envs in the pool.
    num_envs: int
    #: One env's spaces.
    single_observation_space: spaces.Space
    single_action_space: spaces.Space
    #: The envs' ``metadata`` (render modes), render mode and ``EnvSpec`` (if any).
    metadata: dict[str, Any]
    render_mode: Optional[str]
    spec: Any
    #: Program and leading args of a worker process.
    worker_command: Sequence[str]
    #: Who serves the env operations (named in refusals), and the operations served
    #: (:data:`rogue_gym.protocol.ops.ENV_OPS`).
    who: Union[Interpreter, str]
    ops: frozenset[str]
    #: Longest episode the front logs for a replay (:attr:`Core.log`); ``None`` for a kind that
    #: does not render by replay.
    log_steps: Optional[int] = None


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

    def bind(self, core: Core) -> None:
        """Called once the pool runs (per-buffer templates, the pool's info names)."""
        ...

    def batch_views(self, rows: np.ndarray) -> Any:
        """Observations of ``rows`` (``(k, obs_bytes)`` uint8) as a batch of the observation
        space, without a copy."""
        ...

    def obs_filler(self) -> Optional[Callable[[Any, Optional[np.ndarray]], Any]]:
        """``None`` when the slot's observations are whole; else the function that makes a
        batch of them (of every env, or of ``env_ids``) whole, after the call's infos were
        read: the values of leaves of no fixed size, which travel apart. Bound once, at
        construction: a kind without such leaves costs the hot path nothing."""
        ...

    def actions(self, actions: Any, env_ids: Optional[EnvIds]) -> np.ndarray:
        """A batch of actions (for every env, or ``env_ids``) checked, as the pool takes them:
        int64 indices or uint8 bytes."""
        ...

    def seeds(self, seed: Any, mask: Optional[np.ndarray], core: Core) -> Optional[dict[str, Any]]:
        """``reset(seed=seed)``: the episode-seed schedule of a full reset (``mask`` is
        ``None``; ``None`` keeps the current one), or, for a partial reset of the envs of
        ``mask``, seed their next reset (an int ``s`` seeds env ``i`` with ``s + i``, a list
        gives each env's) and return ``None``. ``ValueError``/``TypeError`` for a seed the
        kind cannot take."""
        ...

    def infos(self, core: Core, result: Result, only: Optional[np.ndarray]) -> dict[str, Any]:
        """The infos of a call's rows (``only``: a partial reset's mask; the other rows' info
        is empty), as gymnasium's vector envs return them. The front adds what every kind
        reports (``final_obs``/``final_info`` in SAME_STEP, ``worker_restarted``, ``env_id``)."""
        ...

    def final(self, core: Core, env: int) -> tuple[Any, dict[str, Any]]:
        """(SAME_STEP, after :meth:`infos` of a step where env ``env``'s episode ended) its
        final observation and the info of its last step; the front adds them to the infos as
        gymnasium does (``final_obs``, ``final_info``)."""
        ...

    def call(
        self,
        core: Core,
        op: str,
        name: str,
        arguments: Sequence[tuple[tuple[Any, ...], dict[str, Any]]],
        indices: Sequence[int],
    ) -> list[Any]:
        """Run env operation ``op`` (one of :attr:`ops`) on the envs ``indices`` with
        ``arguments[j]`` for the ``j``-th; one result each."""
        ...

    def info_counts(self) -> tuple[int, int]:
        """Env info rows received so far as typed rows and as pickles (``stats()``)."""
        ...

    def render(self, core: Core) -> Optional[tuple[Any, ...]]:
        """Every env's frame in the render mode."""
        ...
