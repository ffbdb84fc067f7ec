"""The pool as a kind reads it: :class:`CoreView`, the front's :class:`rogue_gym.kinds.view.PoolView`.

It holds the native pool, the arrays over the batch slots and the call state, and nothing of
the front's own objects, so the kind that keeps it makes no reference cycle with
:class:`rogue_gym.front.core.Core` (whose finalizer stops the workers).
"""

from __future__ import annotations

import pickle
from typing import Any, Optional, Sequence

import numpy as np

from ..kinds.view import CallState, PoolLayout
from .worker_errors import native_call, raised_in_worker

__all__ = ["CoreView"]


class CoreView:
    """The declared view of one pool (see :class:`rogue_gym.kinds.view.PoolView`)."""

    __slots__ = ("_cols", "_finals", "_pool", "copy", "layout", "same_step", "state")

    def __init__(
        self,
        pool: Any,
        *,
        copy: bool,
        same_step: bool,
        layout: PoolLayout,
        state: CallState,
        cols: Sequence[dict[str, np.ndarray]],
        finals: Sequence[Optional[np.ndarray]],
    ) -> None:
        self._pool = pool
        self.copy = copy
        self.same_step = same_step
        self.layout = layout
        self.state = state
        self._cols = cols
        self._finals = finals

    def columns(self, slot: int) -> dict[str, np.ndarray]:
        """Views of batch slot ``slot``'s columns."""
        return self._cols[slot]

    def final_rows(self, slot: int) -> np.ndarray:
        """(SAME_STEP) slot ``slot``'s final observations as bytes."""
        rows = self._finals[slot]
        if rows is None:
            raise RuntimeError("final observations are written in SAME_STEP autoreset mode only")
        return rows

    def stage_action_extras(self, extras: Sequence[tuple[int, bytes]]) -> None:
        """Stage the pickled parts of no fixed size of the next step's actions."""
        native_call(self._pool.stage_action_extras, list(extras))

    def call_envs(self, op: str, name: str, requests: Sequence[tuple[int, Any]]) -> list[Any]:
        """Run env operation ``op`` in the workers, one result per ``(env, (args, kwargs))``;
        an env's exception is raised here as itself."""
        encoded = [
            (env, pickle.dumps((op, name, *call), protocol=pickle.HIGHEST_PROTOCOL))
            for env, call in requests
        ]
        results = []
        for env, data in native_call(self._pool.call_envs, encoded):
            status, value = pickle.loads(data)
            if status == "err":
                exc = raised_in_worker(value, f"env {env} during {op}({name!r})")
                raise exc if exc is not None else RuntimeError(f"env {env}: {value}")
            results.append(value)
        return results
