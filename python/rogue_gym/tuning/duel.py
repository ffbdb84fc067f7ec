"""Two candidates side by side: both pools alive, stepped in alternating bursts, the median
ratio of the pairs deciding (bursts a fraction of a second apart see the same machine)."""

from __future__ import annotations

import statistics
from dataclasses import dataclass

from .candidates import Candidate, EnvLike, resolve
from .timing import Live, Target

__all__ = ["Duel", "duel", "side_by_side"]


@dataclass(frozen=True)
class Duel:
    """Two layouts timed side by side: both pools alive, stepped in alternating short bursts
    (the order swapped every pair), so that the machine's drift cancels out of each pair's
    ratio."""

    #: The labels of the two layouts, the faster first.
    first: str
    second: str
    #: Each pair's ratio, ``first / second``.
    ratios: list[float]

    @property
    def ratio(self) -> float:
        """The median of the pairs' ratios (at least 1: the faster is first)."""
        return statistics.median(self.ratios)


def side_by_side(target: Target, a: Candidate, b: Candidate, pairs: int, burst: float) -> Duel:
    with Live(target, a) as live_a, Live(target, b) as live_b:
        ratios = []
        for i in range(pairs):
            if i % 2 == 0:
                ra = live_a.burst(burst)
                rb = live_b.burst(burst)
            else:
                rb = live_b.burst(burst)
                ra = live_a.burst(burst)
            ratios.append(ra / rb)
    if statistics.median(ratios) >= 1:
        return Duel(a.label, b.label, ratios)
    return Duel(b.label, a.label, [1 / r for r in ratios])


def duel(
    env: EnvLike,
    num_envs: int,
    a: Candidate,
    b: Candidate,
    *,
    pairs: int = 24,
    burst: float = 0.25,
) -> Duel:
    """Time layouts ``a`` and ``b`` of ``num_envs`` envs of ``env`` side by side: both pools
    alive, ``pairs`` pairs of alternating bursts of ``burst`` seconds; the faster comes first in
    the result. On a shared machine, whose speed drifts by more than the gap between close
    layouts, this is the measure that holds: runs minutes apart are not comparable."""
    kind, env_fn, _gym_id = resolve(env)
    n = len(env_fn) if isinstance(env_fn, list) else int(num_envs)
    return side_by_side(Target(kind, env_fn, _gym_id, n), a, b, pairs, burst)
