"""Timing one candidate: a fresh pool of it, driven for some seconds of random actions, and
its steps per second and ``stats()`` shares; the estimate of a whole run."""

from __future__ import annotations

import functools
import statistics
import time
from dataclasses import dataclass, field
from typing import Any, Optional

import gymnasium as gym
import numpy as np

from ..protocol.layout import SpaceLayout
from .candidates import HARVEST, Candidate

__all__ = ["Live", "Target", "Timing", "build", "duration", "obs_bytes", "time_run"]


#: Steps before the clock starts.
_WARMUP_STEPS = 20


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


@dataclass(frozen=True)
class Target:
    """What tune times: the env kind, its factory (or factories), its gymnasium id if any, the
    number of envs, and the start-up bound each pool gets."""

    kind: str
    env_fn: Any
    gym_id: Optional[str]
    num_envs: int
    start_timeout: Optional[float] = None


def build(target: Target, c: Candidate) -> Any:
    """``c``'s vector env of ``target``'s envs."""
    from ..vector import PoolVectorEnv, make_vec

    kw = dict(c.kwargs)
    if target.start_timeout is not None and target.kind != "native" and c.mode != "sync":
        kw["start_timeout"] = target.start_timeout
    n, env_fn = target.num_envs, target.env_fn
    fns = env_fn if isinstance(env_fn, list) else [env_fn] * n
    if target.kind == "pettingzoo":
        if c.mode == "sync":
            from ..multi_agent import AgentRows

            return AgentRows(fns)
        return PoolVectorEnv.from_pettingzoo(env_fn, n, **kw)
    if c.mode == "sync":
        return gym.vector.SyncVectorEnv(fns)
    if target.kind == "native":
        return make_vec(n, config="paper", seed=0, **kw)
    if c.mode == "vector":
        assert target.gym_id is not None  # vector candidates exist for gymnasium ids only
        make = functools.partial(vector_env, target.gym_id)
        return PoolVectorEnv.from_vector_env(make, n, **kw)
    return PoolVectorEnv(fns, **kw)


def obs_bytes(kind: str, env_fn: Any) -> int:
    """Bytes of one observation in the pool's batch (one env is built here for a hosted env)."""
    if kind == "native":  # as tune builds it (build)
        from ..vector import make_vec

        env: Any = make_vec(1, config="paper", num_workers=1)
    elif kind == "pettingzoo":  # every agent's row
        from ..multi_agent import AgentRows

        rows = AgentRows([env_fn])
        try:
            return rows.num_envs * SpaceLayout(rows.single_observation_space).stride
        finally:
            rows.close()
    else:
        env = (env_fn[0] if isinstance(env_fn, list) else env_fn)()
    space = env.single_observation_space if kind == "native" else env.observation_space
    try:
        return SpaceLayout(space).stride
    finally:
        env.close()


def vector_env(gym_id: str, n: int) -> Any:
    return gym.make_vec(gym_id, n, vectorization_mode="vector_entry_point")


class Live:
    """One candidate's vector env, built, reset and warmed up, stepped in bursts of random
    actions (sampled in advance) until closed.

    Between bursts nothing runs: an async layout receives every batch still in flight before a
    burst ends and sends them their actions when the next begins. Otherwise its workers would
    go on stepping while the other pool of a duel is timed, slowing that one and starting the
    next burst with steps already done."""

    def __init__(self, target: Target, c: Candidate) -> None:
        self.candidate = c
        self.env = build(target, c)
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

    def __enter__(self) -> Live:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.env.close()


def duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


def time_run(target: Target, timing: Timing, seconds: float) -> Optional[float]:
    """Time ``timing``'s candidate once on a fresh pool, recording its steps/s and shares of
    the time in ``timing`` (or its error: a layout that cannot run is reported, not fatal).
    Returns the seconds the pool took to start, reset and warm up (``None`` if it failed): an
    env that is slow to build makes every candidate slow to start, and the estimate must know
    it."""
    t0 = time.monotonic()
    try:
        with Live(target, timing.candidate) as live:
            start_s = time.monotonic() - t0
            live.reset_stats()
            timing.steps_per_s.append(live.burst(seconds))
            timing.shares.append(live.shares())
    except Exception as exc:
        timing.error = f"{type(exc).__name__}: {exc}"
        return None
    return start_s
