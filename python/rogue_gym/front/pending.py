"""gymnasium's split async API (``step_async``/``step_wait``, ``reset_async``/``reset_wait``,
``call_async``/``call_wait``):
the errors and warnings every env kind raises for calls out of order, written once, with
gymnasium's own types and messages (as ``AsyncVectorEnv`` raises them)."""

from __future__ import annotations

import enum
import multiprocessing as mp
import warnings
from typing import Optional

from gymnasium.error import AlreadyPendingCallError, NoAsyncCallError

__all__ = ["Split", "already_pending", "no_async_call", "timed_out", "warn_close_pending"]


class Split(enum.Enum):
    """A split call (``{value}_async`` then ``{value}_wait``), by the name gymnasium's errors
    give it."""

    STEP = "step"
    RESET = "reset"
    CALL = "call"


def already_pending(caller: str, pending: Split) -> AlreadyPendingCallError:
    """``caller`` (e.g. ``"step_async"``) while ``pending`` waits."""
    return AlreadyPendingCallError(
        f"Calling `{caller}` while waiting for a pending call to `{pending.value}` to complete",
        pending.value,
    )


def no_async_call(what: Split) -> NoAsyncCallError:
    """``{what}_wait`` with no ``{what}_async`` before it."""
    return NoAsyncCallError(
        f"Calling `{what.value}_wait` without any prior call to `{what.value}_async`.", what.value
    )


def timed_out(what: Split, timeout: Optional[float]) -> mp.TimeoutError:
    """``{what}_wait(timeout)`` gave up; the call stays pending (wait again)."""
    return mp.TimeoutError(
        f"The call to `{what.value}_wait` has timed out after {timeout} second(s)."
    )


def warn_close_pending(pending: Split) -> None:
    """``close()`` abandons the pending ``step`` or ``reset``."""
    warnings.warn(
        f"Calling `close` while waiting for a pending call to `{pending.value}` to complete.",
        stacklevel=3,
    )
