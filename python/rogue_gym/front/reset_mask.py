"""The ``reset_mask`` option of a vector env's ``reset``, checked once for every env kind, and
the ``DISABLED`` autoreset rule that relies on it.

The checks, exception types and messages are gymnasium's own (``SyncVectorEnv`` 1.4), so code
written against gymnasium's vector envs sees the same errors from the pool.
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

__all__ = ["check_reset_mask", "partial_mask", "refuse_finished"]


def check_reset_mask(mask: Any, num_envs: int) -> np.ndarray:
    """``mask`` if it is a ``np.bool_`` array of shape ``(num_envs,)`` with at least one
    ``True``; else ``TypeError`` (not an array, or not bool) or ``ValueError`` (shape, or no
    ``True``)."""
    if not isinstance(mask, np.ndarray):
        raise TypeError(f"`options['reset_mask']` must be a numpy array, got {type(mask)}")
    if mask.shape != (num_envs,):
        raise ValueError(
            f"`options['reset_mask']` must have shape `({num_envs},)`, got {mask.shape}"
        )
    if mask.dtype != np.bool_:
        raise TypeError(f"`options['reset_mask']` must have `dtype=np.bool_`, got {mask.dtype}")
    if not mask.any():
        raise ValueError(
            "`options['reset_mask']` must contain a boolean array with at least one True "
            f"value, got reset_mask={mask}"
        )
    return mask


def refuse_finished(done: np.ndarray) -> None:
    """Autoreset mode ``DISABLED``: stepping an env whose episode ended is a ``ValueError``
    naming the envs (the caller resets them with ``reset_mask``)."""
    if done.any():
        envs = np.flatnonzero(done).tolist()
        raise ValueError(
            f"envs {envs} finished their episode: with autoreset_mode DISABLED, reset them with "
            "reset(options={'reset_mask': mask}) before stepping"
        )


def partial_mask(mask: Any, num_envs: int, started: bool) -> Optional[np.ndarray]:
    """The checked ``mask`` of a partial reset, or ``None`` for a full reset (no mask, or one
    that selects every env). A partial reset before the first full one is a ``ValueError``:
    the envs it leaves out would have no episode to keep."""
    if mask is None:
        return None
    mask = check_reset_mask(mask, num_envs)
    if mask.all():
        return None
    if not started:
        raise ValueError(
            "a partial reset (options['reset_mask']) needs a full reset() first: the envs it "
            "leaves out have no episode to keep yet"
        )
    return mask
