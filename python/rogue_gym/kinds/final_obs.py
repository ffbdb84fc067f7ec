"""SAME_STEP's final observations, added to a step's infos as gymnasium's vector envs add them.

A kind's :meth:`~rogue_gym.kinds.spec.Kind.infos` ends with :func:`add_final_obs`: for each
env whose episode ended at a whole-batch call, ``final_obs`` (a fresh copy of its row of the
slot's final-observation area, made whole by the kind) and ``final_info`` (the info of its
last step), with their masks.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ..protocol.infos import add_row_info
from .result import Result, copy_tree, row_of
from .view import PoolView

__all__ = ["FinishFinal", "add_final_obs"]

#: ``(env, obs) -> (obs, info)``: a kind's final observation of ``env`` (``obs``, the slot's
#: row as a batch view, copied) made whole, and the info of its last step.
FinishFinal = Callable[[int, Any], tuple[Any, dict[str, Any]]]


def add_final_obs(
    infos: dict[str, Any],
    view: PoolView,
    result: Result,
    batch_views: Callable[[np.ndarray], Any],
    finish: FinishFinal,
) -> dict[str, Any]:
    """``infos`` with ``final_obs`` and ``final_info`` of every env whose episode ended at
    ``result`` (SAME_STEP, a whole-batch call); unchanged otherwise."""
    if not (view.same_step and result.has_final):
        return infos
    assert result.slot is not None  # has_final: a whole-batch call
    rows = view.final_rows(result.slot)
    n = result.rows
    for env in np.flatnonzero(result.cols["has_final_obs"]).tolist():
        obs, info = finish(env, copy_tree(row_of(batch_views(rows[env : env + 1]), 0)))
        add_row_info(infos, {"final_obs": obs, "final_info": info}, env, n)
    return infos
