"""Crash storms: workers SIGKILLed (and now and then SIGSTOPped) every few hundred ms, the
restarting ones included, under the restart policy. Steps must keep succeeding within their
bounds, restarts must be flagged, and the pool must step normally afterwards and leave nothing
behind (the fixtures check workers and files at teardown)."""

from __future__ import annotations

import os
import random
import signal
import time
from typing import Any, Callable

import gymnasium as gym
import numpy as np
import pytest
from rogue_gym import PoolVectorEnv

from conftest import wait_until

#: Seconds of storm per env kind.
STORM_S = 6.0
STEP_TIMEOUT_S = 1.0


def cartpole() -> gym.Env:
    return gym.make("CartPole-v1")


@pytest.fixture
def hosted() -> Any:
    made: list[PoolVectorEnv] = []

    def factory(**kw: Any) -> PoolVectorEnv:
        env = PoolVectorEnv([cartpole] * 16, **kw)
        made.append(env)
        return env

    yield factory
    for env in made:
        env.close()


def storm(envs: Any, pids: Callable[[], list[int]], seed: int) -> dict[str, int]:
    """Step ``envs`` for STORM_S seconds while signalling random workers."""
    rng = random.Random(seed)
    counts = {"steps": 0, "signals": 0, "flagged": 0}
    t0 = time.monotonic()
    next_signal = t0 + 0.2
    while time.monotonic() - t0 < STORM_S:
        if time.monotonic() >= next_signal:
            victim = rng.choice(pids())
            sig = signal.SIGSTOP if rng.random() < 0.2 else signal.SIGKILL
            try:
                os.kill(victim, sig)
                counts["signals"] += 1
            except ProcessLookupError:
                pass
            next_signal = time.monotonic() + rng.uniform(0.1, 0.4)
        start = time.monotonic()
        _, _, _, truncated, infos = envs.step(envs.action_space.sample())
        # A step waits at most for a hung worker (step_timeout), a restart's start and backoff.
        assert time.monotonic() - start < STEP_TIMEOUT_S + 3.0
        if "worker_restarted" in infos:
            flagged = infos["worker_restarted"]
            assert truncated[flagged].all(), "a restarted env reports truncated"
            counts["flagged"] += int(np.sum(flagged))
        counts["steps"] += 1
    return counts


@pytest.mark.timeout(120)
@pytest.mark.parametrize("kind", ["native", "hosted"])
def test_a_storm_of_worker_kills_never_bricks_the_pool(kind: str, make_vec, hosted) -> None:
    opts = {"num_workers": 4, "step_timeout": STEP_TIMEOUT_S, "max_restarts": 10_000}
    if kind == "native":
        envs = make_vec(16, **opts)
        pids: Callable[[], list[int]] = lambda: envs.worker_pids  # noqa: E731
    else:
        envs = hosted(**opts)
        pids = lambda: envs.worker_pids  # noqa: E731
    envs.reset(seed=0)
    counts = storm(envs, pids, seed=7)
    assert counts["signals"] >= 5, counts
    assert counts["flagged"] > 0, counts
    # After the storm: plain steps, no flags once every stopped worker has been replaced.
    for _ in range(int(STEP_TIMEOUT_S / 0.05) + 40):
        _, _, _, _, infos = envs.step(envs.action_space.sample())
    _, _, _, _, infos = envs.step(envs.action_space.sample())
    assert not np.any(infos.get("worker_restarted", False))
    assert wait_until(lambda: all(os.path.exists(f"/proc/{p}") for p in pids()))
