"""SIGTERM stops a program that uses pools cleanly (workers stopped, shared memory removed).

By default SIGTERM kills Python on the spot: no ``finally`` block or finalizer runs, so the
pools' ``/dev/shm`` files and directories stay behind (the next pool sweeps them, but only then)
while the workers die with their supervisor. When a pool is created, :func:`install` replaces
the *default* SIGTERM action with one that raises ``SystemExit(128 + SIGTERM)``: the program
unwinds as it does on ``sys.exit``, and every pool is closed by its finalizer. A handler the
program installed itself is left alone, and so is any thread but the main one.
"""

from __future__ import annotations

import signal
import threading
from types import FrameType
from typing import Optional

__all__ = ["install"]

#: The exit status of a process stopped by SIGTERM (as a shell reports it).
EXIT_STATUS = 128 + signal.SIGTERM


def _stop(signum: int, frame: Optional[FrameType]) -> None:
    raise SystemExit(EXIT_STATUS)


def install() -> None:
    """Install the cleanup action for SIGTERM if SIGTERM still has its default action."""
    if threading.current_thread() is not threading.main_thread():
        return
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _stop)
