"""Exceptions raised by the pool, and the messages every env kind words alike."""

from __future__ import annotations

from typing import Any, Optional

from gymnasium.error import ClosedEnvironmentError

__all__ = [
    "CorruptInfoError",
    "EnvFailedError",
    "PoolClosedError",
    "WorkerCrashedError",
    "out_of_range",
    "scalar_actions",
]

#: The message of every call on a closed pool, whatever the env kind.
CLOSED_MESSAGE = "the pool is closed: its workers are stopped for good; create a new one"


class PoolClosedError(ClosedEnvironmentError, RuntimeError):
    """A call on a closed pool: gymnasium's ``ClosedEnvironmentError`` (what its vector envs
    raise), and a ``RuntimeError`` as before."""


class CorruptInfoError(RuntimeError):
    """The info bytes a worker wrote for an env could not be decoded: the worker (or code it
    runs, such as an env's C extension) wrote garbage into shared memory. The decoding error is
    the ``__cause__``. The call's results are lost; the pool goes on (``reset()`` starts every
    env afresh).

    Attributes:
        env: the env whose info it was.
        worker: the worker that hosts it, and its process id (``None`` where unknown).
        pid: see ``worker``.
    """

    def __init__(self, env: int, what: str) -> None:
        self.env = env
        self.worker: Optional[int] = None
        self.pid: Optional[int] = None
        self.what = what
        super().__init__(self._message())

    def _message(self) -> str:
        by = "" if self.worker is None else f" (worker {self.worker}, pid {self.pid})"
        return (
            f"the info bytes of env {self.env}{by} cannot be decoded ({self.what}): its worker "
            "wrote garbage into the pool's shared memory, a bug of the env or of code it runs"
        )

    def name_worker(self, worker: int, pid: Optional[int]) -> None:
        """Say which worker hosts the env (the caller's side knows it, the kind does not)."""
        self.worker, self.pid = worker, pid
        self.args = (self._message(),)


class WorkerCrashedError(RuntimeError):
    """A pool worker died or hung and the pool's policy is ``on_worker_failure="raise"``; or,
    under either policy, the restart budget is spent, or a call reached its bound
    (``step_timeout + start_timeout``) while lost workers were still coming back (a crash
    storm, a worker that dies at every start).

    Attributes:
        env: index of the first env hosted by the dead worker.
        envs: indices of all envs hosted by the dead worker.
        worker: index of the worker.
        pid: its process id.
        signal: the signal that killed it (``None`` if it exited).
        exit_code: its exit code (``None`` if killed by a signal or hung).
        stderr_tail: the last lines the worker wrote to stderr.
        restarting: the workers a call that reached its bound still waited for (the pool goes
            on restarting them); empty otherwise.
        deaths: worker failures over the pool's life, when a call reached its bound.

    The pool can be used again after ``reset()`` (not once the restart budget is spent).
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
        restarting: tuple[int, ...] = (),
        deaths: Optional[int] = None,
    ) -> None:
        super().__init__(message)
        self.env = env
        self.envs = tuple(envs)
        self.worker = worker
        self.pid = pid
        self.signal = signal
        self.exit_code = exit_code
        self.stderr_tail = stderr_tail
        self.restarting = tuple(restarting)
        self.deaths = deaths


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


def scalar_actions(n: int) -> str:
    """The message of a ``TypeError`` for one action given to a vector env of ``n`` envs (as
    gymnasium's vector envs refuse it)."""
    return (
        f"expected a batch of actions, one per env ({n}), got a scalar: a vector env takes "
        "an array of shape (num_envs, ...)"
    )


def out_of_range(env: int, action: Any, low: int, high: int, space: Any = None) -> str:
    """The message of a ``ValueError`` for env ``env``'s ``action`` outside ``low`` to
    ``high`` (of ``space``, when named); the pool's own check words it the same."""
    of = "" if space is None else f" of {space}"
    count = f" (range({high + 1}))" if low == 0 else ""
    return (
        f"env {env}: action {action} is out of range{of}; valid actions are {low} to {high}{count}"
    )
