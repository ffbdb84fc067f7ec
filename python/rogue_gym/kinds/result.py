"""One call's result, as the front hands it to a kind: per-env values as columns.

The front makes a :class:`Result` of every pool call; a kind reads it in
:meth:`rogue_gym.kinds.spec.Kind.infos`. The summary flags, the extra-info form and two
helpers over batches of observations (:func:`copy_tree`, :func:`row_of`) live here with it.
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

from .. import _native

__all__ = ["SUMMARY_FINAL", "SUMMARY_RESTARTED", "Extras", "Result", "copy_tree", "row_of"]

#: Bit of a result's summary: some env's worker was restarted during the call.
SUMMARY_RESTARTED: int = _native.SUMMARY_RESTARTED
#: Bit of a result's summary: some env has a final observation (SAME_STEP).
SUMMARY_FINAL: int = _native.SUMMARY_FINAL

#: A call's extra info: ``(rows, data, size, ends)`` (see
#: :func:`rogue_gym.protocol.infos.split_joined`), ``data`` being the joined bytes or, when
#: every env wrote ``size`` bytes of one layout, the slot's extra-info room (``num_envs x
#: extra_bytes``, read in place); or ``None`` when no env wrote any.
Extras = Optional[tuple[Optional[list[int]], Any, int, list[int]]]


class Result:
    """One call's result, in the one form every call has: per-env values as columns.

    A whole-batch call (step, reset, partial reset) has one row per env, in env order, in the
    column buffer of the batch ``slot`` it wrote (reused by a later call that writes the same
    slot). A ``recv`` has one row per env received (``env_ids``), and its observations
    (``obs``): views of the slot the workers wrote them in, or gathered in the ``recv`` buffer.
    """

    __slots__ = ("cols", "env_ids", "extras", "obs", "rows", "slot", "summary")

    def __init__(
        self,
        cols: dict[str, np.ndarray],
        summary: int,
        extras: Extras,
        slot: Optional[int] = None,
        env_ids: Optional[np.ndarray] = None,
        obs: Optional[np.ndarray] = None,
    ) -> None:
        #: Column name to array (``rows`` entries; ``info_int``/``info_bool``: one row each).
        self.cols = cols
        #: ``SUMMARY_*`` bits.
        self.summary = summary
        #: The joined extra info of the rows that wrote some (hosted envs' infos).
        self.extras = extras
        #: The batch slot written (whole-batch calls), else ``None``.
        self.slot = slot
        #: The env of each row (``recv``), else ``None`` (every env, in order).
        self.env_ids = env_ids
        #: The rows' observations as bytes, ``(rows, obs_bytes)`` (``recv``), else ``None``.
        self.obs = obs
        #: Rows of the result.
        self.rows = len(cols["reward"])

    @property
    def restarted(self) -> Optional[np.ndarray]:
        """The rows whose env's worker was restarted during the call, or ``None`` if none."""
        return self.cols["restarted"] if self.summary & SUMMARY_RESTARTED else None

    @property
    def ended(self) -> np.ndarray:
        """The rows whose episode ended at the call (terminated or truncated)."""
        return self.cols["terminated"] | self.cols["truncated"]

    @property
    def has_final(self) -> bool:
        """A whole-batch call where some env's episode ended in SAME_STEP mode: its final
        observation is in the slot's final-observation area."""
        return self.slot is not None and bool(self.summary & SUMMARY_FINAL)

    def ids(self) -> np.ndarray:
        """The env of each row."""
        return np.arange(self.rows) if self.env_ids is None else self.env_ids


def copy_tree(value: Any) -> Any:
    """A copy of a batch (an array, or a dict / tuple of them; anything else is kept)."""
    if isinstance(value, dict):
        return {k: copy_tree(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return tuple(copy_tree(v) for v in value)
    return value.copy() if isinstance(value, np.ndarray) else value


def row_of(tree: Any, i: int) -> Any:
    """Row ``i`` of a batch tree (a dict / tuple of arrays; anything else is kept)."""
    if isinstance(tree, dict):
        return {k: row_of(v, i) for k, v in tree.items()}
    if isinstance(tree, tuple):
        return tuple(row_of(v, i) for v in tree)
    return tree[i] if isinstance(tree, np.ndarray) else tree
