"""Observations handed out without a copy (``PoolVectorEnv(copy=True)``, the default).

The workers write each batch of observations straight into a slot of the pool's shared batch
buffer. Instead of copying that slot into fresh arrays, the caller *lends* it: the arrays it
returns are views of the slot, and the slot counts as lent for as long as any of them (or any
view of them) lives. The workers' next batches go to slots that are not lent, so what the user
holds never changes under them: the same guarantee as a copy, without the copy. When every
other slot is lent (a user keeping many batches), the batch is copied as before, so one slot
always stays free for the workers. Batches smaller than :data:`LEND_MIN_BYTES` are simply
copied. A pool has two slots by default (``batch_slots``): a loop that holds the previous batch
while it steps then gets every other batch lent; three slots lend every batch of such a loop
(docs/performance.md, "Batch slots").
"""

from __future__ import annotations

import weakref
from typing import Any, Callable, Optional

import numpy as np

__all__ = ["LEND_MIN_BYTES", "SlotLender"]
#: Smallest batch of observations (bytes, all envs) that is lent rather than copied: below it a
#: copy costs less than the few microseconds of Python that lending takes per call.
LEND_MIN_BYTES = 64 * 1024


class SlotLender:
    """Which of the pool's batch slots the caller's arrays still use, and the slot the workers
    may write next.

    ``slots`` are the byte rows of each slot (``(num_envs, stride)`` uint8 arrays over shared
    memory); ``views(rows)`` builds the observations (the space's structure) from such rows.
    """

    def __init__(self, slots: list[np.ndarray], views: Callable[[np.ndarray], Any]) -> None:
        self._slots = slots
        self._views = views
        self._lent: list[Optional[weakref.ref[np.ndarray]]] = [None] * len(slots)
        self._last = len(slots) - 1

    def _free(self, slot: int) -> bool:
        ref = self._lent[slot]
        return ref is None or ref() is None

    def lent_mask(self) -> int:
        """The slots an array handed out still uses, as bits (bit ``s``: slot ``s``): the pool
        writes no async answer there."""
        return sum(1 << k for k in range(len(self._slots)) if not self._free(k))

    def next_free(self) -> int:
        """The slot the next batch should go to: the first one after the last batch's that
        no array handed out still uses (one always is free: see :meth:`lend`)."""
        n = len(self._slots)
        for i in range(1, n + 1):
            k = (self._last + i) % n
            if self._free(k):
                return k
        raise RuntimeError("every batch slot is lent; lend() keeps one free")  # unreachable

    def steer(self) -> Optional[int]:
        """The slot to select before the next ``*_shared`` call, or ``None`` when the pool's
        own turn (the slot after the last one it wrote, which :meth:`lend` saw) is free. A
        failed call changes neither the pool's turn nor the slots lent, so this holds after
        one too."""
        free = self.next_free()
        return None if free == (self._last + 1) % len(self._slots) else free

    def lend(self, slot: int) -> Optional[Any]:
        """The observations in ``slot`` as arrays the caller may keep (views of the slot, which
        stays lent while any of them lives), or ``None`` when no other slot is free: then the
        caller must copy them (and ``slot`` stays free for the next batch)."""
        self._last = slot
        if not any(self._free(k) for k in range(len(self._slots)) if k != slot):
            self._lent[slot] = None
            return None
        # A fresh array over the slot whose base is a memoryview, not an array: numpy stops
        # there when it shortens a view's chain of bases, so every view made from it (by us or
        # by the user) keeps *this* array alive, and its death means the slot is free again.
        owner = np.frombuffer(self._slots[slot].data, np.uint8)
        self._lent[slot] = weakref.ref(owner)
        return self._views(owner.reshape(self._slots[slot].shape))
