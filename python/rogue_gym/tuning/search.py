"""The search: every candidate once, the ones within reach again, the leaders again, then
duels; bounded by the time it announces."""

from __future__ import annotations

import dataclasses
import random
import sys
import time
from typing import Any, Optional, Sequence

from .. import _native
from ..front import leases
from ..settings import PoolOptions
from .candidates import Candidate, EnvLike, candidates, resolve
from .duel import Duel, side_by_side
from .report import TuneResult
from .timing import Target, Timing, duration, obs_bytes, time_run

__all__ = ["DUEL_BAND", "KEEP", "LEADERS", "LEADER_BAND", "RIVALS", "estimate_seconds", "tune"]

#: Seconds a fresh pool takes to start and warm up, for the estimate (hosted envs start a
#: Python interpreter per worker; the native game's workers start in milliseconds).
_START_S = {"native": 0.3, "hosted": 1.2, "pettingzoo": 1.2, "sync": 0.2}

#: How many of the fastest candidates are timed again (those within :data:`LEADER_BAND`).
LEADERS = 4
#: The leaders' band: within this fraction of the best median.
LEADER_BAND = 0.1
#: The fastest meets each of the next :data:`RIVALS` whose median is within this fraction of
#: its own in a duel, side by side: single runs of one layout on a busy machine spread by
#: 20-40%, so a layout 15% behind by medians may still be the fastest.
DUEL_BAND = 0.25
#: How many rivals (the next fastest by median) the fastest may meet.
RIVALS = 4
#: After the first round, only the candidates at least this fraction of the best are timed
#: again: the gap between runs of one layout on a busy machine is far smaller.
KEEP = 0.5


def start_factor(c: Candidate, cpus: int) -> float:
    """How much longer than the probe (the most workers, envs built side by side on every CPU)
    ``c``'s envs take to start: a pool of fewer workers than CPUs builds them less in parallel,
    ``SyncVectorEnv`` one after another."""
    workers = 1 if c.mode == "sync" else int(c.kwargs.get("num_workers", cpus))
    return cpus / max(1, min(workers, cpus))


def estimate_seconds(
    kind: str,
    cands: Sequence[Candidate],
    seconds: float,
    rounds: int,
    start_s: Optional[float] = None,
    cpus: int = 1,
    rounds_done: int = 0,
) -> float:
    """How long tune takes (after ``rounds_done`` rounds): each candidate's start-up
    (``start_s`` as measured on the pool with the most workers, scaled by
    :func:`start_factor`; at least the kind's usual) and timed seconds, every round, as many
    rounds again for the leaders, and the duels of the fastest with its rivals (two start-ups
    and ``2 * rounds * seconds`` each)."""
    start = max(_START_S[kind], start_s or 0.0)
    per = [seconds + 0.2 + start * start_factor(c, cpus) for c in cands]
    leaders = min(LEADERS, len(cands))
    slowest = sorted(per, reverse=True)
    duels = min(RIVALS, len(cands) - 1) * (2 * max(per) + 2 * rounds * seconds)
    return sum(per) * (rounds - rounds_done) + sum(slowest[:leaders]) * rounds + duels


def tune(
    env: EnvLike,
    num_envs: int = 64,
    *,
    seconds: float = 2.0,
    rounds: int = 3,
    cpus: Optional[int] = None,
    out: Any = sys.stderr,
) -> TuneResult:
    """Time every candidate layout of ``num_envs`` envs of ``env`` (see the module doc) and
    return the timings, best first; progress and the table go to ``out`` (``None``: quiet).

    Bounded: after the estimated time (printed first) plus half of it, no new run starts."""
    kind, env_fn, gym_id = resolve(env)
    if isinstance(env_fn, list) and len(env_fn) != num_envs:
        num_envs = len(env_fn)
    ncpu = cpus or _native.usable_cores()
    lends = num_envs * obs_bytes(kind, env_fn) >= leases.LEND_MIN_BYTES
    cands = candidates(kind, int(num_envs), gym_id, ncpu, lends)
    say = (lambda m: print(m, file=out, flush=True)) if out is not None else (lambda m: None)
    say(f"tune: timing one start-up of {num_envs} envs")
    target = Target(kind, env_fn, gym_id, int(num_envs))
    timings = {c.label: Timing(c) for c in cands}
    # The pool with the most workers starts its envs side by side on every CPU; the others
    # take longer in proportion, and each gets a start-up bound that allows for it. Its
    # start-up is timed on its first run.
    probe = [c for c in cands if c.mode == "pool"][-1]
    start_s = time_run(target, timings[probe.label], seconds)
    if start_s is not None:
        default = PoolOptions.start_timeout
        target = dataclasses.replace(target, start_timeout=max(default, 3 * ncpu * start_s))
    est = estimate_seconds(kind, cands, seconds, rounds, start_s, ncpu)
    started = "" if start_s is None else f", {start_s:.1f} s to start"
    say(
        f"tune: {len(cands)} layouts x {rounds} rounds of {seconds:g} s, {num_envs} envs"
        f"{started}: about {duration(est)} (at most {duration(1.5 * est)})"
    )
    deadline = time.monotonic() + 1.5 * est
    rng = random.Random(0)

    def run_round(group: list[Candidate], first: bool) -> bool:
        """Time each of ``group`` once, in a new order; ``False`` once the bound has passed
        (the first round always runs whole: every candidate gets one run)."""
        order = list(group)
        rng.shuffle(order)
        for c in order:
            if not first and time.monotonic() > deadline:
                say("tune: time bound reached")
                return False
            if timings[c.label].error is None:
                time_run(target, timings[c.label], seconds)
        return True

    running = cands
    for r in range(rounds):
        group = [c for c in running if len(timings[c.label].steps_per_s) <= r]
        if not run_round(group, first=r == 0):
            break
        say(f"tune: round {r + 1} of {rounds} done")
        if r == 0:
            top = max(t.median for t in timings.values())
            running = [c for c in cands if timings[c.label].median >= KEEP * top > 0]
            if r + 1 < rounds and len(running) < len(cands):
                rest = estimate_seconds(kind, running, seconds, rounds, start_s, ncpu, 1)
                say(
                    f"tune: {len(running)} of {len(cands)} layouts within {KEEP:.0%} of the "
                    f"best go on: about {duration(rest)} more"
                )
    # The leaders (within LEADER_BAND of the best) again, as many rounds: near-ties are where a few
    # noisy runs decide, so they get the most runs.
    best = max(t.median for t in timings.values())
    leaders = sorted(timings.values(), key=lambda t: -t.median)[:LEADERS]
    leaders = [t for t in leaders if t.median >= (1 - LEADER_BAND) * best > 0]
    if len(leaders) > 1:
        for _ in range(rounds):
            if not run_round([t.candidate for t in leaders], first=False):
                break
        say(f"tune: {len(leaders)} leaders timed again")
    ranked = sorted(timings.values(), key=lambda t: t.median, reverse=True)
    # The fastest against each rival within DUEL_BAND, side by side: the winner stays.
    duels: list[Duel] = []
    champion = ranked[0]
    for rival in ranked[1 : 1 + RIVALS]:
        if rival.median < (1 - DUEL_BAND) * ranked[0].median or rival.median <= 0:
            break
        if time.monotonic() > deadline:
            say("tune: time bound reached")
            break
        try:
            d = side_by_side(target, champion.candidate, rival.candidate, 8 * rounds, seconds / 8)
        except Exception:  # both ran before: a failure now leaves the ranking as it is
            continue
        duels.append(d)
        say(f"tune: {d.first} at {d.ratio:.3f}x {d.second}, side by side")
        if d.first == rival.candidate.label:
            champion = rival
    ranked.remove(champion)
    result = TuneResult([champion, *ranked], int(num_envs), seconds, duels, kind)
    say(result.table())
    say(result.advice())
    return result
