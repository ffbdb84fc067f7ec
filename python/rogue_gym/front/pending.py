"""gymnasium's split async API (``step_async``/``step_wait``, ``reset_async``/``reset_wait``,
``call_async``/``call_wait``):
the errors and warnings every env kind raises for calls out of order, written once, with
gymnasium's own types and messages (as ``AsyncVectorEnv`` raises them)."""

from __future__ import annotations

import multiprocessing as mp
import warnings
from typing import Optional

from gymnasium.error import AlreadyPendingCallError, NoAsyncCallError

__all__ = ["already_pending", "no_async_call", "timed_out", "warn_close_pending"]


def already_pending(caller: str, pending: str) -> AlreadyPendingCallError:
    """``caller`` (e.g. ``"step_async"``) while ``pending`` (``"step"``, ``"reset"`` or
    ``"call"``) waits."""
    return AlreadyPendingCallError(
        f"Calling `{caller}` while waiting for a pending call to `{pending}` to complete", pending
    )


def no_async_call(what: str) -> NoAsyncCallError:
    """``{what}_wait`` with no ``{what}_async`` before it."""
    return NoAsyncCallError(
        f"Calling `{what}_wait` without any prior call to `{what}_async`.", what
    )


def timed_out(what: str, timeout: Optional[float]) -> mp.TimeoutError:
    """``{what}_wait(timeout)`` gave up; the call stays pending (wait again)."""
    return mp.TimeoutError(f"The call to `{what}_wait` has timed out after {timeout} second(s).")


def warn_close_pending(pending: str) -> None:
    """``close()`` abandons the pending ``step`` or ``reset``."""
    warnings.warn(
        f"Calling `close` while waiting for a pending call to `{pending}` to complete.",
        stacklevel=3,
    )
