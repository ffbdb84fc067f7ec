"""What a kind may read of the pool it serves: the declared view, and the call state.

The front builds one :class:`PoolView` per vector env and hands it to its kind once
(:meth:`rogue_gym.kinds.spec.Kind.bind`); the kind keeps it and reads the pool through these
names only. The view holds the native pool and arrays over shared memory, not the front's
objects, so a kind that keeps it makes no reference cycle with the front.

:class:`CallState` is the call lifecycle every facade shares (whether the envs were reset,
which episodes ended, the envs of the last ``recv``, the slot of the last whole-batch call, the
episode log): one object, written by the front (:mod:`rogue_gym.front`, and
:mod:`rogue_gym.envpool` over it), read by kinds through :attr:`PoolView.state`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional, Protocol, Sequence

import numpy as np

from .episode_log import EpisodeLog

__all__ = ["CallState", "PoolLayout", "PoolView"]


@dataclass
class CallState:
    """The call lifecycle of one vector env (see the module doc)."""

    #: Envs in the pool.
    num_envs: int
    #: Whether the envs were reset (a reset, or ``async_reset``) since the pool started.
    started: bool = False
    #: The envs whose episode ended at their last call (terminated or truncated).
    ended: np.ndarray = field(init=False)
    #: The envs of the last ``recv`` (a ``send`` without env ids answers them), or ``None``.
    last_ids: Optional[np.ndarray] = None
    #: The batch slot written by the last whole-batch call (``None`` before the first).
    slot: Optional[int] = None
    #: Each env's actions since its episode began (kinds that render by replay), or ``None``.
    log: Optional[EpisodeLog] = None

    def __post_init__(self) -> None:
        self.ended = np.zeros(self.num_envs, bool)

    def restart(self) -> None:
        """Every env was reset: nothing ended, no ``recv`` to answer."""
        self.started = True
        self.ended[:] = False
        self.last_ids = None


@dataclass(frozen=True)
class PoolLayout:
    """One env's observation as the workers write it, the pool's info value names, and its
    number of batch slots."""

    obs_shape: tuple[int, ...]
    obs_dtype: str
    info_names: tuple[str, ...]
    slots: int


class PoolView(Protocol):
    """The pool as a kind reads it: eight names."""

    #: The facade hands out observations that are the caller's to keep (``copy=True``).
    copy: bool
    #: SAME_STEP autoreset (the workers write each ended episode's final observation).
    same_step: bool
    #: The observation and info names the running pool has.
    layout: PoolLayout
    #: The call lifecycle (read only: the front writes it).
    state: CallState

    def columns(self, slot: int) -> dict[str, np.ndarray]:
        """Views of the columns batch slot ``slot`` holds (per-env rewards, flags, counters,
        info rows), written by the last call that wrote the slot."""
        ...

    def final_rows(self, slot: int) -> np.ndarray:
        """(SAME_STEP) the final observations of slot ``slot`` as bytes, ``(num_envs,
        obs_bytes)``: row ``e`` is env ``e``'s when its ``has_final_obs`` column is set."""
        ...

    def stage_action_extras(self, extras: Sequence[tuple[int, bytes]]) -> None:
        """Stage the pickled parts of no fixed size of the next step's actions, ``(env id,
        bytes)`` each: the step command to each env's worker carries them."""
        ...

    def call_envs(self, op: str, name: str, requests: Sequence[tuple[int, Any]]) -> list[Any]:
        """Run env operation ``op`` with ``name`` in the workers: ``requests`` are ``(env,
        (args, kwargs))``; one result each, or the env's own exception raised here."""
        ...
