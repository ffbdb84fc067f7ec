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
or as shared-memory views (``copy=False``); the EnvPool-style async loop (``send``/``recv``
with ``batch_size`` = one worker's envs) where the workers divide the envs; and for a
gymnasium id with its own vector entry point, one such vector env per worker
(:meth:`rogue_gym.PoolVectorEnv.from_vector_env`). ``SyncVectorEnv`` in this process is timed
too: where it is faster, tune says so and recommends it. Each candidate runs in a fresh pool
for ``seconds`` of random actions after a warm-up, every candidate once per round, in a new
order each round, then the leaders (up to four, within 10% of the best) as many rounds again,
then, when the two fastest are within 10%, as many back-to-back pairs of those two, whose
median ratio decides between them (pairs see the same machine: a shared VM's speed drifts by
more than the gap between close layouts); the table gives each one's median steps/s and its
``stats()`` breakdown.
The whole run is bounded: tune times one start-up of the envs (an env slow to build makes
every candidate slow to start), says how long it will take, and stops timing new rounds when
the bound has passed.
"""

from __future__ import annotations

import argparse
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

from .registration import ENV_ID

__all__ = ["Candidate", "TuneResult", "main", "tune"]

#: Seconds a fresh pool takes to start and warm up, for the estimate (hosted envs start a
#: Python interpreter per worker; the native game's workers start in milliseconds).
_START_S = {"native": 0.3, "hosted": 1.2, "sync": 0.2}
#: How many of the fastest candidates are timed again (those within 10% of the best).
LEADERS = 4
#: The two fastest are timed back to back, in pairs, when the second is within this fraction
#: of the first: run by run, the machine's drift cancels out of their ratio.
DUEL_BAND = 0.1
#: Steps before the clock starts.
_WARMUP_STEPS = 20
NATIVE_NAMES = (ENV_ID, "native", "rogue")

EnvLike = Union[str, Callable[[], gym.Env], Sequence[Callable[[], gym.Env]]]


@dataclass(frozen=True)
class Candidate:
    """One layout: the keyword arguments of the vector env, and how it is stepped."""

    #: ``"pool"`` (``step``), ``"async"`` (``send``/``recv``), ``"vector"`` (one vector env per
    #: worker) or ``"sync"`` (gymnasium's ``SyncVectorEnv`` in this process).
    mode: str
    kwargs: dict[str, Any] = field(default_factory=dict)

    @property
    def label(self) -> str:
        """A short name for the table."""
        if self.mode == "sync":
            return "SyncVectorEnv"
        args = ", ".join(f"{k}={v}" for k, v in self.kwargs.items())
        return f"{self.mode}: {args}"


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
    #: The final duel of the two fastest, if they were close: ``(first, second, median of
    #: first/second over back-to-back pairs)``; its winner is ranked first.
    duel: Optional[tuple[str, str, float]] = None

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
        if self.duel is not None:
            first, second, ratio = self.duel
            lines.append(f"back to back: {first} at {ratio:.3f}x {second} (median of pairs)")
        return "\n".join(lines)

    def advice(self) -> str:
        """The line to paste (or the advice to use ``SyncVectorEnv``)."""
        pool = self.best_pool
        if self.best.candidate.mode == "sync" or pool is None:
            x = 0.0
            if pool is not None:
                duel = self.duel is not None and self.duel[1] == pool.candidate.label
                x = self.duel[2] if duel and self.duel else self.best.median / pool.median
            ratio = f" ({x:.2f}x the best pool layout)" if pool else ""
            return (
                f"SyncVectorEnv is the fastest here{ratio}: this env is too cheap for worker "
                "processes at this size on this machine; use gymnasium.vector.SyncVectorEnv"
            )
        c = pool.candidate
        kwargs = ", ".join(f"{k}={v!r}" for k, v in c.kwargs.items())
        if c.mode == "vector":
            return f"best: PoolVectorEnv.from_vector_env(vector_env_fn, {self.num_envs}, {kwargs})"
        how = " (then step with send/recv)" if c.mode == "async" else ""
        return f"best: make_vec(env, {self.num_envs}, {kwargs}){how}"


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


def candidates(kind: str, num_envs: int, gym_id: Optional[str], cpus: int) -> list[Candidate]:
    """Every layout tune times for ``num_envs`` envs on ``cpus`` CPUs."""
    out: list[Candidate] = []
    workers = [w for w in range(1, 2 * cpus + 1) if w <= num_envs]
    for w in workers:
        for copy in (True, False):
            out.append(Candidate("pool", {"num_workers": w, "copy": copy}))
        if w > 1 and num_envs % w == 0:
            out.append(Candidate("async", {"num_workers": w, "batch_size": num_envs // w}))
    if kind == "hosted" and gym_id is not None and gym.spec(gym_id).vector_entry_point:
        for w in workers:
            out.append(Candidate("vector", {"num_workers": w}))
    if kind == "hosted":
        out.append(Candidate("sync"))
    return out


def _build(kind: str, env_fn: Any, gym_id: Optional[str], num_envs: int, c: Candidate) -> Any:
    import rogue_gym

    kw = dict(c.kwargs)
    fns = env_fn if isinstance(env_fn, list) else [env_fn] * num_envs
    if c.mode == "sync":
        return gym.vector.SyncVectorEnv(fns)
    if kind == "native":
        return rogue_gym.make_vec(num_envs, config="paper", seed=0, **kw)
    if c.mode == "vector":
        assert gym_id is not None  # vector candidates exist for gymnasium ids only
        make = functools.partial(_vector_env, gym_id)
        return rogue_gym.PoolVectorEnv.from_vector_env(make, num_envs, **kw)
    return rogue_gym.PoolVectorEnv(fns, **kw)


def _vector_env(gym_id: str, n: int) -> Any:
    return gym.make_vec(gym_id, n, vectorization_mode="vector_entry_point")


def _time_one(
    kind: str, env_fn: Any, gym_id: Optional[str], num_envs: int, c: Candidate, seconds: float
) -> tuple[float, tuple[float, float, float]]:
    """Steps/s of one fresh pool, and its shares of the time (env, transport, caller)."""
    env = _build(kind, env_fn, gym_id, num_envs, c)
    try:
        env.action_space.seed(0)
        acts = [env.action_space.sample() for _ in range(16)]
        if c.mode == "async":
            env.async_reset()
            rows = c.kwargs["batch_size"]
            sub = [np.asarray(a)[:rows] for a in acts]
            for i in range(_WARMUP_STEPS):
                env.recv()
                env.send(sub[i % 16])
            env.stats(reset=True)
            steps, t0 = 0, time.perf_counter()
            while time.perf_counter() - t0 < seconds:
                for i in range(10):
                    env.recv()
                    env.send(sub[i % 16])
                steps += 10 * rows
        else:
            env.reset(seed=0)
            for i in range(_WARMUP_STEPS):
                env.step(acts[i % 16])
            if hasattr(env, "stats"):
                env.stats(reset=True)
            steps, t0 = 0, time.perf_counter()
            while time.perf_counter() - t0 < seconds:
                for i in range(10):
                    env.step(acts[i % 16])
                steps += 10 * num_envs
        rate = steps / (time.perf_counter() - t0)
        shares = (float("nan"),) * 3
        if hasattr(env, "stats"):
            s = env.stats()
            shares = (s.env_share, s.transport_share, s.caller_share)
        return rate, shares
    finally:
        env.close()


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


def estimate_seconds(
    kind: str, n_candidates: int, seconds: float, rounds: int, start_s: Optional[float] = None
) -> float:
    """How long tune takes: each candidate's start-up (``start_s``, as measured; at least the
    kind's usual) and timed seconds, every round, as many rounds again for the leaders, and as
    many pairs for the final duel."""
    per = seconds + max(_START_S[kind], start_s or 0.0) + 0.2
    return (n_candidates + min(LEADERS, n_candidates) + 2) * rounds * per


def _start_seconds(
    kind: str, env_fn: Any, gym_id: Optional[str], num_envs: int, c: Candidate
) -> float:
    """Seconds ``c``'s pool takes to start, reset and close (an env that is slow to build makes
    every candidate slow to start: the estimate must know it)."""
    t0 = time.monotonic()
    env = _build(kind, env_fn, gym_id, num_envs, c)
    try:
        env.reset(seed=0)
    finally:
        env.close()
    return time.monotonic() - t0


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

    Bounded: after the estimated time (printed first) plus half of it, no new round starts."""
    kind, env_fn, gym_id = _resolve(env)
    if isinstance(env_fn, list) and len(env_fn) != num_envs:
        num_envs = len(env_fn)
    cands = candidates(kind, int(num_envs), gym_id, cpus or os.cpu_count() or 1)
    say = (lambda m: print(m, file=out, flush=True)) if out is not None else (lambda m: None)
    say(f"tune: timing one start-up of {num_envs} envs")
    # The pool with the most workers starts its envs side by side, as most candidates do.
    probe = [c for c in cands if c.mode == "pool"][-1]
    try:
        start_s: Optional[float] = _start_seconds(kind, env_fn, gym_id, int(num_envs), probe)
    except Exception:  # the candidates' own runs report what fails
        start_s = None
    est = estimate_seconds(kind, len(cands), seconds, rounds, start_s)
    started = "" if start_s is None else f", {start_s:.1f} s to start each"
    say(
        f"tune: {len(cands)} layouts x {rounds} rounds of {seconds:g} s, {num_envs} envs"
        f"{started}: about {_duration(est)} (at most {_duration(1.5 * est)})"
    )
    timings = {c.label: Timing(c) for c in cands}
    deadline = time.monotonic() + 1.5 * est
    rng = random.Random(0)

    def run_round(group: list[Candidate]) -> None:
        order = list(group)
        rng.shuffle(order)
        for c in order:
            t = timings[c.label]
            if t.error is not None:
                continue
            try:
                rate, shares = _time_one(kind, env_fn, gym_id, int(num_envs), c, seconds)
            except Exception as exc:  # a layout that cannot run is reported, not fatal
                t.error = f"{type(exc).__name__}: {exc}"
                continue
            t.steps_per_s.append(rate)
            t.shares.append(shares)

    for r in range(rounds):
        if r and time.monotonic() > deadline:
            say(f"tune: time bound reached after {r} rounds")
            break
        run_round(cands)
        say(f"tune: round {r + 1} of {rounds} done")
    # The leaders (within 10% of the best) again, as many rounds: near-ties are where a few
    # noisy runs decide, so they get the most runs.
    best = max(t.median for t in timings.values())
    leaders = sorted(timings.values(), key=lambda t: -t.median)[:LEADERS]
    leaders = [t for t in leaders if t.median >= 0.9 * best]
    if len(leaders) > 1:
        for _ in range(rounds):
            if time.monotonic() > deadline:
                say("tune: time bound reached")
                break
            run_round([t.candidate for t in leaders])
        say(f"tune: {len(leaders)} leaders timed again")
    ranked = sorted(timings.values(), key=lambda t: t.median, reverse=True)
    duel = None
    if len(ranked) > 1 and ranked[1].median >= (1 - DUEL_BAND) * ranked[0].median > 0:
        first, second = ranked[0], ranked[1]
        ratios = []
        for i in range(rounds):
            if time.monotonic() > deadline:
                say("tune: time bound reached")
                break
            pair = {}
            for t in (first, second) if i % 2 == 0 else (second, first):
                try:
                    rate, _ = _time_one(kind, env_fn, gym_id, int(num_envs), t.candidate, seconds)
                except Exception:  # it ran before: a failure now leaves the ranking as it is
                    break
                pair[t.candidate.label] = rate
            if len(pair) == 2:
                ratios.append(pair[first.candidate.label] / pair[second.candidate.label])
        if ratios:
            ratio = statistics.median(ratios)
            if ratio < 1:
                ranked[0], ranked[1] = second, first
                ratio = 1 / ratio
            duel = (ranked[0].candidate.label, ranked[1].candidate.label, ratio)
            say(f"tune: the two fastest timed back to back, {len(ratios)} pairs")
    result = TuneResult(ranked, int(num_envs), seconds, duel)
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
