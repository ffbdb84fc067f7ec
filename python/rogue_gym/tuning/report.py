"""What tune measured: the table and the advice."""

from __future__ import annotations

import statistics
from dataclasses import dataclass, field
from typing import Optional

from .duel import Duel
from .timing import Timing

__all__ = ["TuneResult"]

#: Threads and serial closer than this (a fraction of the serial best) are called a tie.
TIE = 0.03


@dataclass
class TuneResult:
    """What tune measured, best first."""

    timings: list[Timing]
    num_envs: int
    seconds: float
    #: The fastest against each rival within :data:`DUEL_BAND`, side by side, in the
    #: order run; the last winner is ranked first.
    duels: list[Duel] = field(default_factory=list)
    #: What was tuned: ``"native"``, ``"hosted"`` (gymnasium envs) or ``"pettingzoo"``.
    kind: str = "hosted"

    @property
    def best(self) -> Timing:
        """The fastest candidate."""
        return self.timings[0]

    @property
    def best_pool(self) -> Optional[Timing]:
        """The fastest layout of the pool (not ``SyncVectorEnv``)."""
        return next((t for t in self.timings if t.candidate.mode != "sync" and t.median > 0), None)

    def table(self) -> str:
        """The table: one row per candidate, best first."""
        lines = [
            f"{'layout':<58} {'steps/s':>12} {'env':>5} {'transport':>9} {'caller':>6}",
        ]
        for t in self.timings:
            if t.error is not None:
                lines.append(f"{t.candidate.label:<58} {'failed':>12}  {t.error[:60]}")
                continue
            shares = [statistics.median(s[i] for s in t.shares) for i in range(3)]
            env, transport, caller = (f"{x:.0%}" if x == x else "-" for x in shares)
            lines.append(
                f"{t.candidate.label:<58} {t.median:>12,.0f} {env:>5} {transport:>9} {caller:>6}"
            )
        for d in self.duels:
            lines.append(
                f"side by side: {d.first} at {d.ratio:.3f}x {d.second} "
                f"(median of {len(d.ratios)} pairs)"
            )
        threads = self.threads_against_serial()
        if threads is not None:
            lines.append(threads)
        return "\n".join(lines)

    def threads_against_serial(self) -> Optional[str]:
        """Which is faster for this env, its envs on threads of their worker or one after the
        other: the best layout of each (where tune timed both)."""
        pools = [t for t in self.timings if t.candidate.mode != "sync" and t.median > 0]
        threaded = [t for t in pools if "env_concurrency" in t.candidate.kwargs]
        serial = [t for t in pools if "env_concurrency" not in t.candidate.kwargs]
        if not threaded or not serial:
            return None
        a, b = max(threaded, key=lambda t: t.median), max(serial, key=lambda t: t.median)
        x = a.median / b.median
        procs = (a.candidate.kwargs["num_workers"], b.candidate.kwargs["num_workers"])
        if abs(x - 1) <= TIE:
            verdict = (
                f"threads and serial are within {TIE:.0%} for this env (threads in "
                f"{procs[0]} worker processes, serial in {procs[1]})"
            )
        else:
            verdict = f"{'threads' if x > 1 else 'serial'} is faster for this env"
        return (
            f"env_concurrency: {verdict}; the best threaded layout {a.median:,.0f} steps/s "
            f"({x:.2f}x the best serial one, {b.median:,.0f})"
        )

    def advice(self) -> str:
        """The line to paste (or the advice to use ``SyncVectorEnv``)."""
        pool = self.best_pool
        if self.best.candidate.mode == "sync" or pool is None:
            x = 0.0
            if pool is not None:
                x = self.best.median / pool.median
                for d in self.duels:
                    if (d.first, d.second) == (self.best.candidate.label, pool.candidate.label):
                        x = d.ratio
            ratio = f" ({x:.2f}x the best pool layout)" if pool else ""
            if self.kind == "pettingzoo":
                return (
                    f"a loop over the envs in this process is the fastest here{ratio}: use "
                    "rogue_gym.multi_agent.AgentRows(env_fns)"
                )
            return (
                f"SyncVectorEnv is the fastest here{ratio}: this env is too cheap for worker "
                "processes at this size on this machine; use gymnasium.vector.SyncVectorEnv"
            )
        c = pool.candidate
        kwargs = ", ".join(f"{k}={v!r}" for k, v in c.kwargs.items())
        if self.kind == "pettingzoo":
            return f"best: PoolVectorEnv.from_pettingzoo(env_fn, {self.num_envs}, {kwargs})"
        if c.mode == "vector":
            return f"best: PoolVectorEnv.from_vector_env(vector_env_fn, {self.num_envs}, {kwargs})"
        how = {
            "async": " (then step with send/recv)",
            "harvest": (
                f" (then recv(min_batch=1, max_batch={self.num_envs}, timeout=1e-3) and send "
                "actions to the envs received)"
            ),
        }.get(c.mode, "")
        return f"best: make_vec(env, {self.num_envs}, {kwargs}){how}"
