"""Let the pool choose its layout: time the candidate layouts of one env side by side and print
the best keyword arguments.

Command line::

    python -m rogue_gym.tune CartPole-v1 [--num-envs 64] [--seconds 2] [--rounds 3]
    python -m rogue_gym.tune my_pkg.envs:make_env --num-envs 256
    python -m rogue_gym.tune RogueGym-v0        # the native game (paper config)

From Python: ``rogue_gym.tune(env, num_envs=64)`` with a gymnasium id, an env factory (a
callable, or ``"module:callable"``), a list of ``env_fns`` (one per env), or ``"RogueGym-v0"``;
it returns a :class:`TuneResult`.

The candidates: ``num_workers`` from 1 to twice the CPU count; observations lent (``copy=True``)
or as shared-memory views (``copy=False``), and where the batch is large enough to be lent, lent
from three batch slots (``batch_slots=3``: every batch lent, one more batch of ``/dev/shm``); the EnvPool-style async loop (``send``/``recv``)
with ``batch_size`` = one worker's envs and half the envs, and with one worker per env (up
to :data:`MAX_ONE_PER_ENV` envs); TorchRL's deadline harvest (``harvest``: ``recv(min_batch=1,
max_batch=num_envs, timeout=1e-3)``, every env received sent at once), which serves envs of
uneven speed (slow resets) best; and for a
gymnasium id with its own vector entry point, one such vector env per worker
(:meth:`rogue_gym.PoolVectorEnv.from_vector_env`). ``SyncVectorEnv`` in this process is timed
too: where it is faster, tune says so and recommends it. Each candidate runs in a fresh pool
for ``seconds`` of random actions after a warm-up, every candidate in the first round, then
those within half of the best (the others are out of the running, and out of the time) in the
rounds after, in a new order each round; then the leaders (up to four, within 10% of the best)
as many rounds again.
Last, the fastest meets each of the next four within 25% in a duel (:func:`duel`): both pools
alive, stepped in ``8 * rounds`` pairs of alternating bursts of ``seconds / 8``, whose median
ratio decides; the winner stays on. Runs minutes apart see a shared machine at different
speeds, by more than the gap between close layouts; bursts a fraction of a second apart do
not. The table gives each one's median steps/s, its ``stats()`` breakdown and the duels.
The whole run is bounded: tune times one start-up of the envs (an env slow to build makes
every candidate slow to start, and gets a start-up bound to match), says how long it will take,
and starts no new run once that time and half again have passed.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import importlib
import os
import random
import statistics
import sys
import time
import types
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Sequence, Union

import gymnasium as gym
import numpy as np

from .front import leases
from .protocol.layout import SpaceLayout
from .registration import ENV_ID
from .settings import PoolOptions

__all__ = ["Candidate", "Duel", "TuneResult", "duel", "main", "tune"]

#: Seconds a fresh pool takes to start and warm up, for the estimate (hosted envs start a
#: Python interpreter per worker; the native game's workers start in milliseconds).
_START_S = {"native": 0.3, "hosted": 1.2, "sync": 0.2}
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
#: Steps before the clock starts.
_WARMUP_STEPS = 20
NATIVE_NAMES = (ENV_ID, "native", "rogue")

EnvLike = Union[str, Callable[[], gym.Env], Sequence[Callable[[], gym.Env]]]


@dataclass(frozen=True)
class Candidate:
    """One layout: the keyword arguments of the vector env, and how it is stepped."""

    #: ``"pool"`` (``step``), ``"async"`` (``send``/``recv`` of ``batch_size`` envs),
    #: ``"harvest"`` (``recv`` with a deadline, :data:`HARVEST`), ``"vector"`` (one vector env
    #: per worker) or ``"sync"`` (gymnasium's ``SyncVectorEnv`` in this process).
    mode: str
    kwargs: dict[str, Any] = field(default_factory=dict)

    @property
    def label(self) -> str:
        """A short name for the table."""
        if self.mode == "sync":
            return "SyncVectorEnv"
        args = ", ".join(f"{k}={v}" for k, v in self.kwargs.items())
        return f"{self.mode}: {args}"

    @classmethod
    def from_label(cls, label: str) -> Candidate:
        """The candidate a :attr:`label` names (its keyword values are ints or bools)."""
        if label == "SyncVectorEnv":
            return cls("sync")
        mode, _, args = label.partition(": ")
        kwargs: dict[str, Any] = {}
        for arg in args.split(", "):
            key, _, value = arg.partition("=")
            kwargs[key] = value == "True" if value in ("True", "False") else int(value)
        return cls(mode, kwargs)


@dataclass
class Timing:
    """A candidate's runs: steps/s, and the pool's shares of the time (env, transport,
    caller) of each run."""

    candidate: Candidate
    steps_per_s: list[float] = field(default_factory=list)
    shares: list[tuple[float, float, float]] = field(default_factory=list)
    error: Optional[str] = None

    @property
    def median(self) -> float:
        """Median steps/s (0 if it never ran)."""
        return statistics.median(self.steps_per_s) if self.steps_per_s else 0.0


@dataclass
class TuneResult:
    """What tune measured, best first."""

    timings: list[Timing]
    num_envs: int
    seconds: float
    #: The fastest against each rival within :data:`DUEL_BAND`, side by side, in the
    #: order run; the last winner is ranked first.
    duels: list[Duel] = field(default_factory=list)

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
        return "\n".join(lines)

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
            return (
                f"SyncVectorEnv is the fastest here{ratio}: this env is too cheap for worker "
                "processes at this size on this machine; use gymnasium.vector.SyncVectorEnv"
            )
        c = pool.candidate
        kwargs = ", ".join(f"{k}={v!r}" for k, v in c.kwargs.items())
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


#: Most envs for which tune tries one worker per env.
MAX_ONE_PER_ENV = 64
#: The deadline harvest's ``recv`` arguments besides ``max_batch`` (TorchRL's, pytorch/rl PR
#: #4182).
HARVEST = {"min_batch": 1, "timeout": 1e-3}


def _resolve(env: EnvLike) -> tuple[str, Any, Optional[str]]:
    """``(kind, env_fn or env_fns, gym_id)`` of what tune was given."""
    if isinstance(env, (list, tuple)):
        if not env or not all(callable(f) for f in env):
            raise TypeError("env_fns must be a non-empty list of callables building envs")
        return "hosted", list(env), None
    if isinstance(env, str) and env in NATIVE_NAMES:
        return "native", None, None
    if isinstance(env, str) and ":" in env and env not in gym.registry:
        module, _, name = env.partition(":")
        return "hosted", getattr(importlib.import_module(module), name), None
    if isinstance(env, str):
        if env not in gym.registry:
            raise ValueError(
                f"{env!r} is not a registered gymnasium id, 'module:callable' or {ENV_ID}"
            )
        return "hosted", functools.partial(gym.make, env), env
    if callable(env):
        return "hosted", env, None
    raise TypeError(f"tune needs a gymnasium id, an env factory or {ENV_ID!r}, got {env!r}")


def candidates(
    kind: str, num_envs: int, gym_id: Optional[str], cpus: int, lends: bool = False
) -> list[Candidate]:
    """Every layout tune times for ``num_envs`` envs on ``cpus`` CPUs; ``lends``: the batch is
    large enough to be lent (``copy=True``), so three batch slots (every batch lent, one more
    batch of ``/dev/shm``) are a candidate too."""
    out: list[Candidate] = []
    workers = [w for w in range(1, 2 * cpus + 1) if w <= num_envs]
    for w in workers:
        for copy in (True, False):
            out.append(Candidate("pool", {"num_workers": w, "copy": copy}))
        if lends:
            out.append(Candidate("pool", {"num_workers": w, "copy": True, "batch_slots": 3}))
        if w > 1:
            for b in sorted({num_envs // w, num_envs // 2} - {0}):
                out.append(Candidate("async", {"num_workers": w, "batch_size": b}))
    # One worker per env: envs that sleep (slow resets, I/O) cost no CPU while they wait, and
    # no env waits behind another.
    spread = [num_envs] if workers[-1] < num_envs <= MAX_ONE_PER_ENV else []
    for w in spread:
        out.append(Candidate("async", {"num_workers": w, "batch_size": max(1, num_envs // 2)}))
    for w in sorted({min(cpus, num_envs), *spread}):
        out.append(Candidate("harvest", {"num_workers": w, "batch_size": 1}))
    if kind == "hosted" and gym_id is not None and gym.spec(gym_id).vector_entry_point:
        for w in workers:
            out.append(Candidate("vector", {"num_workers": w}))
    if kind == "hosted":
        out.append(Candidate("sync"))
    return out


@dataclass(frozen=True)
class _Target:
    """What tune times: the env kind, its factory (or factories), its gymnasium id if any, the
    number of envs, and the start-up bound each pool gets."""

    kind: str
    env_fn: Any
    gym_id: Optional[str]
    num_envs: int
    start_timeout: Optional[float] = None


def _build(target: _Target, c: Candidate) -> Any:
    """``c``'s vector env of ``target``'s envs."""
    import rogue_gym

    kw = dict(c.kwargs)
    if target.start_timeout is not None and target.kind == "hosted" and c.mode != "sync":
        kw["start_timeout"] = target.start_timeout
    n, env_fn = target.num_envs, target.env_fn
    fns = env_fn if isinstance(env_fn, list) else [env_fn] * n
    if c.mode == "sync":
        return gym.vector.SyncVectorEnv(fns)
    if target.kind == "native":
        return rogue_gym.make_vec(n, config="paper", seed=0, **kw)
    if c.mode == "vector":
        assert target.gym_id is not None  # vector candidates exist for gymnasium ids only
        make = functools.partial(_vector_env, target.gym_id)
        return rogue_gym.PoolVectorEnv.from_vector_env(make, n, **kw)
    return rogue_gym.PoolVectorEnv(fns, **kw)


def _obs_bytes(kind: str, env_fn: Any) -> int:
    """Bytes of one observation in the pool's batch (one env is built here for a hosted env)."""
    if kind == "native":  # as tune builds it (_build)
        from .vector import make_vec

        env: Any = make_vec(1, config="paper", num_workers=1)
    else:
        env = (env_fn[0] if isinstance(env_fn, list) else env_fn)()
    space = env.single_observation_space if kind == "native" else env.observation_space
    try:
        return SpaceLayout(space).stride
    finally:
        env.close()


def _vector_env(gym_id: str, n: int) -> Any:
    return gym.make_vec(gym_id, n, vectorization_mode="vector_entry_point")


class _Live:
    """One candidate's vector env, built, reset and warmed up, stepped in bursts of random
    actions (sampled in advance) until closed.

    Between bursts nothing runs: an async layout receives every batch still in flight before a
    burst ends and sends them their actions when the next begins. Otherwise its workers would
    go on stepping while the other pool of a duel is timed, slowing that one and starting the
    next burst with steps already done."""

    def __init__(self, target: _Target, c: Candidate) -> None:
        self.candidate = c
        self.env = _build(target, c)
        self.n = target.num_envs
        self.async_ = c.mode in ("async", "harvest")
        # async: envs received and not yet answered, and envs sent and not yet received.
        self._held: list[int] = []
        self.outstanding = 0
        try:
            self.env.action_space.seed(0)
            acts = [self.env.action_space.sample() for _ in range(16)]
            self.acts = acts
            if self.async_:
                self.env.async_reset()
                self.outstanding = self.n
            else:
                self.env.reset(seed=0)
            self._steps(_WARMUP_STEPS)
            self._drain()
        except BaseException:
            self.env.close()
            raise

    def _recv(self) -> np.ndarray:
        """Async: one recv as the candidate makes it; the env ids received."""
        if self.candidate.mode == "harvest":
            while True:
                try:
                    ids = self.env.recv(max_batch=self.outstanding, **HARVEST)[4]["env_id"]
                    break
                except TimeoutError:
                    continue
        else:
            ids = self.env.recv()[4]["env_id"]
        self.outstanding -= len(ids)
        return ids

    def _send(self, ids: Any, i: int) -> None:
        self.env.send(np.asarray(self.acts[i % 16])[: len(ids)], env_id=ids)
        self.outstanding += len(ids)

    def _steps(self, n: int) -> int:
        """``n`` steps (lockstep) or recvs (async); the env steps they made."""
        env, acts = self.env, self.acts
        if self.async_:
            done = 0
            for i in range(n):
                ids = self._recv()
                self._send(ids, i)
                done += len(ids)
            return done
        for i in range(n):
            env.step(acts[i % 16])
        return n * self.n

    def _resume(self) -> None:
        """Async: answer the envs held since the last burst."""
        if self._held:
            self._send(np.asarray(self._held), 0)
        self._held = []

    def _drain(self) -> int:
        """Async: receive every env in flight and hold it; the envs received."""
        got = 0
        while self.outstanding > 0:
            ids = self._recv() if self.candidate.mode == "harvest" else self._recv_rest()
            self._held.extend(int(i) for i in ids)
            got += len(ids)
        return got

    def _recv_rest(self) -> np.ndarray:
        ids = self.env.recv(min_batch=min(self.outstanding, self.env.batch_size))[4]["env_id"]
        self.outstanding -= len(ids)
        return ids

    def burst(self, seconds: float) -> float:
        """Steps/s over about ``seconds`` of stepping, with nothing left running after it."""
        steps, t0 = 0, time.perf_counter()
        self._resume()
        while time.perf_counter() - t0 < seconds:
            steps += self._steps(10)
        steps += self._drain()
        return steps / (time.perf_counter() - t0)

    def reset_stats(self) -> None:
        """Start the pool's counters afresh (``SyncVectorEnv`` has none)."""
        if hasattr(self.env, "stats"):
            self.env.stats(reset=True)

    def shares(self) -> tuple[float, float, float]:
        """The pool's shares of the time since :meth:`reset_stats`: env, transport, caller."""
        if not hasattr(self.env, "stats"):
            return (float("nan"),) * 3
        s = self.env.stats()
        return (s.env_share, s.transport_share, s.caller_share)

    def __enter__(self) -> _Live:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.env.close()


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


def _duel(target: _Target, a: Candidate, b: Candidate, pairs: int, burst: float) -> Duel:
    with _Live(target, a) as live_a, _Live(target, b) as live_b:
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
    kind, env_fn, _gym_id = _resolve(env)
    n = len(env_fn) if isinstance(env_fn, list) else int(num_envs)
    return _duel(_Target(kind, env_fn, _gym_id, n), a, b, pairs, burst)


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


def _start_factor(c: Candidate, cpus: int) -> float:
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
    :func:`_start_factor`; at least the kind's usual) and timed seconds, every round, as many
    rounds again for the leaders, and the duels of the fastest with its rivals (two start-ups
    and ``2 * rounds * seconds`` each)."""
    start = max(_START_S[kind], start_s or 0.0)
    per = [seconds + 0.2 + start * _start_factor(c, cpus) for c in cands]
    leaders = min(LEADERS, len(cands))
    slowest = sorted(per, reverse=True)
    duels = min(RIVALS, len(cands) - 1) * (2 * max(per) + 2 * rounds * seconds)
    return sum(per) * (rounds - rounds_done) + sum(slowest[:leaders]) * rounds + duels


def _time_run(target: _Target, timing: Timing, seconds: float) -> Optional[float]:
    """Time ``timing``'s candidate once on a fresh pool, recording its steps/s and shares of
    the time in ``timing`` (or its error: a layout that cannot run is reported, not fatal).
    Returns the seconds the pool took to start, reset and warm up (``None`` if it failed): an
    env that is slow to build makes every candidate slow to start, and the estimate must know
    it."""
    t0 = time.monotonic()
    try:
        with _Live(target, timing.candidate) as live:
            start_s = time.monotonic() - t0
            live.reset_stats()
            timing.steps_per_s.append(live.burst(seconds))
            timing.shares.append(live.shares())
    except Exception as exc:
        timing.error = f"{type(exc).__name__}: {exc}"
        return None
    return start_s


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
    kind, env_fn, gym_id = _resolve(env)
    if isinstance(env_fn, list) and len(env_fn) != num_envs:
        num_envs = len(env_fn)
    ncpu = cpus or os.cpu_count() or 1
    lends = num_envs * _obs_bytes(kind, env_fn) >= leases.LEND_MIN_BYTES
    cands = candidates(kind, int(num_envs), gym_id, ncpu, lends)
    say = (lambda m: print(m, file=out, flush=True)) if out is not None else (lambda m: None)
    say(f"tune: timing one start-up of {num_envs} envs")
    target = _Target(kind, env_fn, gym_id, int(num_envs))
    timings = {c.label: Timing(c) for c in cands}
    # The pool with the most workers starts its envs side by side on every CPU; the others
    # take longer in proportion, and each gets a start-up bound that allows for it. Its
    # start-up is timed on its first run.
    probe = [c for c in cands if c.mode == "pool"][-1]
    start_s = _time_run(target, timings[probe.label], seconds)
    if start_s is not None:
        default = PoolOptions.start_timeout
        target = dataclasses.replace(target, start_timeout=max(default, 3 * ncpu * start_s))
    est = estimate_seconds(kind, cands, seconds, rounds, start_s, ncpu)
    started = "" if start_s is None else f", {start_s:.1f} s to start"
    say(
        f"tune: {len(cands)} layouts x {rounds} rounds of {seconds:g} s, {num_envs} envs"
        f"{started}: about {_duration(est)} (at most {_duration(1.5 * est)})"
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
                _time_run(target, timings[c.label], seconds)
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
                    f"best go on: about {_duration(rest)} more"
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
            d = _duel(target, champion.candidate, rival.candidate, 8 * rounds, seconds / 8)
        except Exception:  # both ran before: a failure now leaves the ranking as it is
            continue
        duels.append(d)
        say(f"tune: {d.first} at {d.ratio:.3f}x {d.second}, side by side")
        if d.first == rival.candidate.label:
            champion = rival
    ranked.remove(champion)
    result = TuneResult([champion, *ranked], int(num_envs), seconds, duels)
    say(result.table())
    say(result.advice())
    return result


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Command-line entry point."""
    p = argparse.ArgumentParser(
        prog="python -m rogue_gym.tune",
        description="Time the pool's candidate layouts for one env and print the best.",
    )
    p.add_argument("env", help=f"a gymnasium id, module:callable, or {ENV_ID} (the native game)")
    p.add_argument("--num-envs", type=int, default=64)
    p.add_argument("--seconds", type=float, default=2.0, help="timed seconds per run")
    p.add_argument("--rounds", type=int, default=3)
    args = p.parse_args(argv)
    if args.num_envs < 1 or args.seconds <= 0 or args.rounds < 1:
        p.error("--num-envs, --seconds and --rounds must be positive")
    tune(args.env, args.num_envs, seconds=args.seconds, rounds=args.rounds, out=sys.stdout)
    return 0


class _CallableModule(types.ModuleType):
    """This module, callable: ``rogue_gym.tune(env, num_envs)`` is :func:`tune`."""

    def __call__(self, env: EnvLike, num_envs: int = 64, **kwargs: Any) -> TuneResult:
        return tune(env, num_envs, **kwargs)


sys.modules[__name__].__class__ = _CallableModule

if __name__ == "__main__":
    sys.exit(main())
