"""Crash storms and workers that cannot start, under the restart policy.

* A storm the machine keeps up with: steps keep succeeding, restarts are flagged.
* A storm faster than restarts, longer than the backoff's growth: every call returns or raises
  within its bound (``step_timeout + start_timeout``), and one ``reset()`` after the storm makes
  the pool step again.
* A worker that dies at every start: the call raises within its bound, naming it; the budget,
  when spent, says so; once the worker can start, one ``reset()`` recovers.

The fixtures close every pool and check that no worker or file is left behind.
"""

from __future__ import annotations

import functools
import os
import random
import signal
import tempfile
import threading
import time
from pathlib import Path
from typing import Any, Callable

import gymnasium as gym
import numpy as np
import pytest
from rogue_gym import PoolVectorEnv, WorkerCrashedError, _native

from conftest import pid_alive, wait_until
from hosted_envs import slow_in_workers

#: Seconds of the storm faster than restarts, per env kind.
STORM_S = 4.0
#: Seconds of the storm the machine keeps up with: it signals from the stepping loop, and a
#: stopped worker holds a step for step_timeout, so it needs longer to send enough signals.
KEEP_UP_STORM_S = 6.0
STEP_TIMEOUT_S = 1.0
#: Timeouts of the fast storm: every call must end within their sum.
FAST_STEP_TIMEOUT_S = 0.5
FAST_START_TIMEOUT_S = 2.0
#: What a busy 2-core machine may add to a call's bound before the test sees it return
#: (the pool itself gives up 20 ms early).
SCHEDULING_SLACK_S = 0.2


def cartpole() -> gym.Env:
    return gym.make("CartPole-v1")


@pytest.fixture
def hosted() -> Any:
    made: list[PoolVectorEnv] = []

    def factory(env_fns: Any = None, num_envs: int = 16, **kw: Any) -> PoolVectorEnv:
        env = PoolVectorEnv(env_fns or [cartpole] * num_envs, **kw)
        made.append(env)
        return env

    yield factory
    for env in made:
        pids = env.worker_pids
        env.close()
        assert wait_until(lambda pids=pids: not any(pid_alive(p) for p in pids))


def make_kind(kind: str, make_vec: Any, hosted: Any, **opts: Any) -> Any:
    if kind == "native":
        return make_vec(16, **opts)
    return hosted(**opts)


def storm(envs: Any, seed: int) -> dict[str, int]:
    """Step ``envs`` for KEEP_UP_STORM_S seconds while signalling random workers."""
    rng = random.Random(seed)
    counts = {"steps": 0, "signals": 0, "flagged": 0}
    t0 = time.monotonic()
    next_signal = t0 + 0.2
    while time.monotonic() - t0 < KEEP_UP_STORM_S:
        if time.monotonic() >= next_signal:
            victim = rng.choice(envs.worker_pids)
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


@pytest.mark.timeout(60)
@pytest.mark.parametrize("kind", ["native", "hosted"])
def test_a_storm_of_worker_kills_never_bricks_the_pool(kind: str, make_vec, hosted) -> None:
    opts = {"num_workers": 4, "step_timeout": STEP_TIMEOUT_S, "max_restarts": 10_000}
    envs = make_kind(kind, make_vec, hosted, **opts)
    envs.reset(seed=0)
    counts = storm(envs, seed=7)
    assert counts["signals"] >= 5, counts
    assert counts["flagged"] > 0, counts
    assert envs.restarts > 0
    # After the storm: plain steps, no flags once every stopped worker has been replaced.
    for _ in range(int(STEP_TIMEOUT_S / 0.05) + 40):
        _, _, _, _, infos = envs.step(envs.action_space.sample())
    _, _, _, _, infos = envs.step(envs.action_space.sample())
    assert not np.any(infos.get("worker_restarted", False))
    assert wait_until(lambda: all(os.path.exists(f"/proc/{p}") for p in envs.worker_pids))


class Killer(threading.Thread):
    """SIGKILLs a random live worker every ``interval`` seconds, starting ones included (it
    reads the pids without waiting for the call in flight)."""

    def __init__(self, pids: Callable[[], list[int]], interval: float) -> None:
        super().__init__(daemon=True)
        self.pids, self.interval = pids, interval
        self.rng = random.Random(3)
        self.halt = threading.Event()
        self.kills = 0

    def run(self) -> None:
        while not self.halt.wait(self.interval):
            live = [p for p in self.pids() if p and pid_alive(p)]
            if live:
                try:
                    os.kill(self.rng.choice(live), signal.SIGKILL)
                    self.kills += 1
                except ProcessLookupError:
                    pass


@pytest.mark.timeout(60)
@pytest.mark.parametrize("kind", ["native", "hosted"])
def test_every_call_keeps_its_bound_in_a_storm_faster_than_restarts(
    kind: str, make_vec, hosted
) -> None:
    # A kill every 30 ms: many replacements die while starting, so backoffs grow to their cap
    # and some calls cannot get their workers back. Each call must return or raise
    # WorkerCrashedError within step_timeout + start_timeout; a raise is followed by reset(),
    # as a training loop would do.
    opts = {
        "num_workers": 4,
        "step_timeout": FAST_STEP_TIMEOUT_S,
        "start_timeout": FAST_START_TIMEOUT_S,
        "max_restarts": 100_000,
    }
    envs = make_kind(kind, make_vec, hosted, **opts)
    bound = FAST_STEP_TIMEOUT_S + FAST_START_TIMEOUT_S
    envs.reset(seed=0)
    killer = Killer(lambda: envs.worker_pids, 0.03)
    killer.start()
    calls, raised, longest, need_reset = 0, 0, 0.0, False
    t0 = time.monotonic()
    try:
        while time.monotonic() - t0 < STORM_S:
            start = time.monotonic()
            try:
                if need_reset:
                    envs.reset()
                    need_reset = False
                else:
                    _, _, _, truncated, infos = envs.step(envs.action_space.sample())
                    flagged = infos.get("worker_restarted", np.zeros(16, bool))
                    assert truncated[flagged].all(), "a restarted env reports truncated"
            except WorkerCrashedError as err:
                assert err.restarting, f"the error names the workers still restarting: {err}"
                assert "call reset() to continue" in str(err)
                raised += 1
                need_reset = True
            calls += 1
            longest = max(longest, time.monotonic() - start)
            assert longest <= bound + SCHEDULING_SLACK_S, (
                f"a call took {longest:.2f} s, over its bound of {bound} s"
            )
    finally:
        killer.halt.set()
        killer.join()
    assert killer.kills >= 30, killer.kills
    assert envs.restarts > 10
    # After the storm: one reset, then plain steps with no restart flags.
    envs.reset()
    for _ in range(20):
        _, _, _, _, infos = envs.step(envs.action_space.sample())
        assert not np.any(infos.get("worker_restarted", False))
    assert calls > raised


def dies_in_workers_while(marker: str, creator: int) -> Callable[[], gym.Env]:
    """An env fn whose worker exits (code 3) at start while ``marker`` exists."""

    def make() -> gym.Env:
        if os.getpid() != creator and os.path.exists(marker):
            os._exit(3)
        return gym.make("CartPole-v1")

    return make


@pytest.mark.timeout(60)
def test_a_worker_that_dies_at_every_start_makes_calls_raise_within_their_bound(
    hosted, tmp_path: Path
) -> None:
    marker = str(tmp_path / "die")
    fn = dies_in_workers_while(marker, os.getpid())
    envs = hosted([fn] * 4, num_workers=2, step_timeout=0.3, start_timeout=1.2)
    bound = 0.3 + 1.2
    envs.reset(seed=0)
    Path(marker).touch()
    os.kill(envs.worker_pids[1], signal.SIGKILL)
    for call in (lambda: envs.step(envs.action_space.sample()), envs.reset):
        start = time.monotonic()
        with pytest.raises(WorkerCrashedError) as info:
            call()
        assert time.monotonic() - start <= bound + SCHEDULING_SLACK_S
        err = info.value
        assert err.restarting == (1,) and err.worker == 1, err
        assert err.exit_code == 3 and err.deaths >= 3, err
        assert "could not be brought back within this call's bound" in str(err)
        assert "exited with code 3 while starting" in str(err)
    # Once it can start again, one reset recovers every env.
    os.unlink(marker)
    envs.reset(seed=1)
    for _ in range(5):
        _, _, _, _, infos = envs.step(envs.action_space.sample())
        assert "worker_restarted" not in infos


@pytest.mark.timeout(60)
def test_a_spent_restart_budget_is_reported_as_such(hosted, tmp_path: Path) -> None:
    marker = str(tmp_path / "die")
    fn = dies_in_workers_while(marker, os.getpid())
    envs = hosted([fn] * 4, num_workers=2, step_timeout=0.3, start_timeout=5.0, max_restarts=3)
    envs.reset(seed=0)
    Path(marker).touch()
    os.kill(envs.worker_pids[0], signal.SIGKILL)
    start = time.monotonic()
    with pytest.raises(WorkerCrashedError, match=r"restart budget exhausted \(3 restarts\)"):
        envs.step(envs.action_space.sample())
    assert time.monotonic() - start < 2.0, "the budget ends the call before its bound"


@pytest.mark.timeout(120)
def test_every_class_shows_restarts_and_worker_pids(make_vec) -> None:
    """After a worker is killed and replaced, ``restarts`` counts it and ``worker_pids`` shows
    the new process, through the gymnasium and the SB3 classes of both kinds."""
    pytest.importorskip("stable_baselines3")
    from rogue_gym.sb3 import PoolVecEnv, RogueVecEnv
    from stable_baselines3.common.vec_env import VecEnv

    made = {
        "RogueVectorEnv": make_vec(4, num_workers=2),
        "RogueVecEnv": RogueVecEnv(4, num_workers=2, seed=0),
        "PoolVectorEnv": PoolVectorEnv([cartpole] * 4, num_workers=2),
        "PoolVecEnv": PoolVecEnv([cartpole] * 4, num_workers=2),
    }
    try:
        for name, env in made.items():
            env.reset()
            before = list(env.worker_pids)
            assert env.restarts == 0 and len(before) == 2 and all(map(pid_alive, before)), name
            os.kill(before[1], signal.SIGKILL)
            assert wait_until(lambda b=before[1]: not pid_alive(b))
            if isinstance(env, VecEnv):
                env.step_async(np.zeros(4, np.int64))
                env.step_wait()
            else:
                env.step(np.zeros(4, np.int64))
            after = env.worker_pids
            assert env.restarts == 1, name
            assert after[0] == before[0] and after[1] != before[1] and pid_alive(after[1]), name
    finally:
        for name, env in made.items():
            if name != "RogueVectorEnv":  # the fixture closes that one
                env.close()


def children() -> set[int]:
    """This process's live child processes."""
    out = set()
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == os.getpid() and fields[0] != "Z":
                out.add(int(entry))
    return out


@pytest.mark.timeout(60)
def test_ctrl_c_stops_a_slow_start_up_at_once_and_leaves_nothing(sigint_handler) -> None:
    """Workers whose envs take a minute to build, and a start-up bound of two: Ctrl-C half a
    second in raises KeyboardInterrupt at once, not when the start-up ends, and the workers and
    the pool's files are gone."""
    before, shm = children(), set(os.listdir("/dev/shm"))
    # A runtime directory of its own (short: iceoryx2's socket paths are limited), removed
    # whatever the outcome.
    with tempfile.TemporaryDirectory(prefix="rgc", dir="/tmp") as own_dir:
        own = Path(own_dir) / "rt"
        fn = functools.partial(slow_in_workers, os.getpid(), 60.0)
        timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
        t0 = time.monotonic()
        timer.start()
        try:
            with pytest.raises(KeyboardInterrupt):
                PoolVectorEnv([fn] * 2, num_workers=2, start_timeout=120.0, runtime_dir=str(own))
        finally:
            timer.cancel()
        assert time.monotonic() - t0 < 10
        assert wait_until(lambda: children() <= before), "workers left running"
    # Files of pools that other processes run meanwhile (their directories are in the default
    # runtime directory; this pool's were in its own) are not this pool's.
    others = Path(_native.default_runtime_dir())
    left = {
        f
        for f in set(os.listdir("/dev/shm")) - shm
        if not (others / f"{f.split('_')[0]}.d").exists()
    }
    assert not left, f"pool files left behind: {sorted(left)[:3]}"
