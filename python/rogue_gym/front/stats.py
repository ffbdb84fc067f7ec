"""Live pool statistics (``envs.stats()``): where the time goes, and whether the pool is
healthy.

The workers count their own steps and time in shared memory (:mod:`rogue_gym._native`'s
``Pool.stats``, no message per step); the caller's clock splits its own time into time inside
the pool's calls (waiting on the workers) and time between them (your code: the policy, the
learner, and the Python front end); the front end counts how observations were handed out and
how infos travelled. ``str(stats)`` is a one-line health summary.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Optional

__all__ = ["PoolStats", "WorkerStats"]


@dataclass(frozen=True)
class WorkerStats:
    """One worker's counters (a worker replaced after a crash goes on in its predecessor's)."""

    #: Env steps and resets served.
    env_steps: int = 0
    #: Step and reset commands served.
    commands: int = 0
    #: Seconds inside the envs' step/reset (with ``env_concurrency``: the envs' times added
    #: up, so more than the time that passed).
    env_s: float = 0.0
    #: Of ``env_s``, the seconds the envs spent off the CPU, waiting (I/O, a sleep, a lock):
    #: counted with ``env_concurrency`` (each env on a thread), 0 otherwise.
    env_wait_s: float = 0.0
    #: Seconds waiting for the next command (for actions).
    wait_s: float = 0.0
    #: Seconds publishing answers (the block, and infos too long for it).
    publish_s: float = 0.0
    #: Times the worker was replaced after dying or hanging.
    restarts: int = 0
    #: Times it was replaced by plan (``recycle_after_steps``, ``recycle_above_rss``).
    recycles: int = 0
    #: Times it did not answer within ``step_timeout`` (among ``restarts``).
    timeouts: int = 0
    #: Info bytes that did not fit the block and travelled beside it, in a file.
    spilled_bytes: int = 0
    #: The last failure, as a sentence.
    last_failure: Optional[str] = None

    @classmethod
    def from_native(cls, d: dict[str, Any]) -> WorkerStats:
        """From the native pool's dict (nanoseconds)."""
        return cls(
            env_steps=int(d["env_steps"]),
            commands=int(d["commands"]),
            env_s=d["env_ns"] / 1e9,
            env_wait_s=d["env_wait_ns"] / 1e9,
            wait_s=d["wait_ns"] / 1e9,
            publish_s=d["publish_ns"] / 1e9,
            restarts=int(d["restarts"]),
            recycles=int(d["recycles"]),
            timeouts=int(d["timeouts"]),
            spilled_bytes=int(d["spilled_bytes"]),
            last_failure=d["last_failure"],
        )


@dataclass(frozen=True)
class PoolStats:
    """The pool's statistics over a span of the caller's time (since the pool started, or
    since ``stats(reset=True)``)."""

    #: Seconds of the caller's time covered: between plus inside the pool's calls.
    seconds: float = 0.0
    #: Seconds between the pool's calls: the caller's own code and the Python front end.
    caller_s: float = 0.0
    #: Seconds inside the pool's calls: waiting on the workers, and the transport.
    waiting_s: float = 0.0
    #: Native calls made.
    calls: int = 0
    #: One entry per worker.
    workers: tuple[WorkerStats, ...] = ()
    #: Env info rows that travelled as typed rows (decoded in one go) or as pickles.
    info_rows_typed: int = 0
    info_rows_pickled: int = 0
    #: Observation batches handed out: lent (no copy, the slot kept), copied, or as views of
    #: shared memory (``copy=False``).
    batches_lent: int = 0
    batches_copied: int = 0
    batches_viewed: int = 0
    #: Bytes the pool needs in ``/dev/shm`` (each worker's channels; checked against its free
    #: space at creation), and of its own buffers (the batch slots, episode books and counters:
    #: memory of the process, reserved at creation): not counts, the same in a difference of
    #: two readings.
    shm_bytes: int = 0
    buffer_bytes: int = 0
    #: The machine as the pool sees it when read: ``cores`` it may use at once, the ``demand``
    #: it counts (its workers, and each other live pool of yours: its workers and its caller),
    #: how its workers wait for their next command (``worker_pace``: ``"expected"``,
    #: ``"short"`` or ``"block"``), whether its ``caller_polls`` through a call, and the ``others`` (each a dict: ``pool``, ``pid``, ``workers``,
    #: ``caller_polls``, ``cores``). docs/performance.md, "Many pools on one machine".
    machine: dict[str, Any] = dataclasses.field(default_factory=dict)

    @property
    def env_steps(self) -> int:
        """Env steps (and resets) of every worker."""
        return sum(w.env_steps for w in self.workers)

    @property
    def restarts(self) -> int:
        """Worker restarts."""
        return sum(w.restarts for w in self.workers)

    @property
    def recycles(self) -> int:
        """Planned worker replacements (recycling), apart from :attr:`restarts`."""
        return sum(w.recycles for w in self.workers)

    @property
    def steps_per_s(self) -> float:
        """Env steps per second of the caller's time."""
        return self.env_steps / self.seconds if self.seconds > 0 else 0.0

    @property
    def env_share(self) -> float:
        """The share of the caller's time the envs took: the workers' mean busy time, at most
        the time the caller waited."""
        if self.seconds <= 0 or not self.workers:
            return 0.0
        busy = sum(w.env_s for w in self.workers) / len(self.workers)
        return min(busy, self.waiting_s) / self.seconds

    @property
    def caller_share(self) -> float:
        """The share of the caller's time spent between the pool's calls."""
        return self.caller_s / self.seconds if self.seconds > 0 else 0.0

    @property
    def transport_share(self) -> float:
        """The share of the caller's time spent waiting that the envs do not explain: the
        transport (commands, shared memory, wake-ups, decoding) and idle workers."""
        if self.seconds <= 0:
            return 0.0
        return max(0.0, self.waiting_s / self.seconds - self.env_share)

    def __sub__(self, base: PoolStats) -> PoolStats:
        """The counts since ``base`` (an earlier reading of the same pool)."""
        changes: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            if f.name not in ("workers", "shm_bytes", "buffer_bytes", "machine"):
                changes[f.name] = getattr(self, f.name) - getattr(base, f.name)
        workers = []
        for k, w in enumerate(self.workers):
            b = base.workers[k] if k < len(base.workers) else WorkerStats()
            workers.append(
                WorkerStats(
                    **{
                        f.name: getattr(w, f.name) - getattr(b, f.name)
                        for f in dataclasses.fields(w)
                        if f.name != "last_failure"
                    },
                    last_failure=w.last_failure,
                )
            )
        return dataclasses.replace(self, workers=tuple(workers), **changes)

    def __str__(self) -> str:
        """One line: steps/s, the env's, the transport's and the caller's shares of the
        time, and restarts."""
        return (
            f"{self.steps_per_s:,.0f} steps/s | env {self.env_share:.0%} | transport "
            f"{self.transport_share:.0%} | caller {self.caller_share:.0%} | restarts "
            f"{self.restarts}"
        )
