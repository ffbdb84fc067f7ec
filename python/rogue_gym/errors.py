"""Exceptions raised by the pool."""

from __future__ import annotations

from typing import Optional

__all__ = ["EnvFailedError", "WorkerCrashedError"]


class WorkerCrashedError(RuntimeError):
    """A pool worker died or hung and the pool's policy is ``on_worker_failure="raise"``.

    Attributes:
        env: index of the first env hosted by the dead worker.
        envs: indices of all envs hosted by the dead worker.
        worker: index of the worker.
        pid: its process id.
        signal: the signal that killed it (``None`` if it exited).
        exit_code: its exit code (``None`` if killed by a signal or hung).
        stderr_tail: the last lines the worker wrote to stderr.

    The pool can be used again after ``reset()``.
    """

    def __init__(
        self,
        message: str,
        *,
        env: Optional[int] = None,
        envs: tuple[int, ...] = (),
        worker: Optional[int] = None,
        pid: Optional[int] = None,
        signal: Optional[int] = None,
        exit_code: Optional[int] = None,
        stderr_tail: str = "",
    ) -> None:
        super().__init__(message)
        self.env = env
        self.envs = tuple(envs)
        self.worker = worker
        self.pid = pid
        self.signal = signal
        self.exit_code = exit_code
        self.stderr_tail = stderr_tail


class EnvFailedError(RuntimeError):
    """An env raised (or returned an error) in its reset or step inside a worker.

    Hosted gymnasium envs re-raise the env's own exception instead, with the worker-side
    traceback attached as a note; this class is for the rest (native env errors, and hosted
    exceptions that could not be carried over).

    Attributes:
        env: index of the env that failed.
        worker: index of its worker.
        pid: the worker's process id (the worker is still alive).
        context: what the env was doing, e.g. ``"step (episode 3, seed 7, step 12)"``.
        detail: the env's own message.

    The pool can be used again after ``reset()``.
    """

    def __init__(
        self,
        message: str,
        *,
        env: int,
        worker: int,
        pid: int,
        context: str,
        detail: str,
    ) -> None:
        super().__init__(message)
        self.env = env
        self.worker = worker
        self.pid = pid
        self.context = context
        self.detail = detail
