"""Envs that wait, on threads inside their worker (``env_concurrency``; docs/performance.md,
"Envs that wait"): a waiting env holds only its thread, and in the async API each env is
handed out as soon as it is ready. What holds with serial workers holds with threads: each
env's trajectory whatever the thread count or layout, an env that raises fails alone, a
worker killed mid-reset costs its envs one restarted episode, calls stay within their bounds
(close() too, with envs asleep), deadlines and fair service."""

from __future__ import annotations

import os
import time
from collections import Counter
from typing import Any

import numpy as np
import pytest
import rogue_gym

from conftest import pool_files
from hosted_envs import FailingSleeper, JitterEnv, SleepEnv, SlowResetEnv, SpecialError


def _pool(fns: list[Any], **kw: Any) -> Any:
    return rogue_gym.PoolVectorEnv(fns, **kw)


def _closed(envs: Any) -> None:
    name = envs._core.name
    envs.close()
    assert pool_files(name) == []


def _sync_run(env_concurrency: Any, workers: int, steps: int = 25) -> list[np.ndarray]:
    envs = _pool([JitterEnv] * 6, num_workers=workers, env_concurrency=env_concurrency)
    try:
        obs, infos = envs.reset(seed=7)
        out = [obs.copy(), infos["start"].copy()]
        rng = np.random.default_rng(0)
        for _ in range(steps):
            obs, rew, term, trunc, infos = envs.step(rng.integers(0, 3, 6))
            out += [obs.copy(), rew.copy(), term.copy(), infos["x"].copy()]
        return out
    finally:
        _closed(envs)


def test_each_env_plays_the_same_trajectory_whatever_the_threads_and_workers() -> None:
    reference = _sync_run("serial", 1)
    for concurrency, workers in (("threads", 1), (2, 2), ("threads", 3), (1, 2)):
        got = _sync_run(concurrency, workers)
        for a, b in zip(reference, got):
            np.testing.assert_array_equal(a, b, err_msg=f"{concurrency}, {workers} workers")


def test_the_async_api_hands_out_each_env_as_it_is_ready_with_its_own_trajectory() -> None:
    """Per env, the rows ``recv`` hands out follow the env's own trajectory (the sync run's),
    whatever order the envs finish in."""
    envs = _pool([JitterEnv] * 6, num_workers=2, env_concurrency="threads", batch_size=1)
    sync = _pool([JitterEnv] * 6, num_workers=1)
    try:
        obs, _ = sync.reset(seed=3)
        expected = {e: [obs[e].copy()] for e in range(6)}
        for _ in range(6):
            obs = sync.step(np.ones(6, np.int64))[0]
            for e in range(6):
                expected[e].append(obs[e].copy())
        obs0, _ = envs.reset(seed=3)  # the async loop starts from a sync reset (TorchRL's way)
        got: dict[int, list[np.ndarray]] = {e: [obs0[e].copy()] for e in range(6)}
        envs.send(np.ones(6, np.int64), np.arange(6))
        order: list[int] = []
        while min(len(v) for v in got.values()) < 7:
            obs, _, _, _, info = envs.recv()
            for row, e in enumerate(info["env_id"].tolist()):
                got[e].append(obs[row].copy())
                order.append(e)
                if len(got[e]) < 7:
                    envs.send(np.ones(1, np.int64), [e])
        for e in range(6):
            np.testing.assert_array_equal(np.array(got[e][:7]), np.array(expected[e]))
        assert order != sorted(order), "the envs came back in the order they finished"
    finally:
        _closed(envs)
        _closed(sync)


def test_an_env_that_raises_fails_alone_among_sleeping_mates() -> None:
    """Env 2 raises at its third step while its worker-mates sleep: the call raises its
    exception (type and message), the other envs' results are handed out, and a reset
    recovers."""
    envs = _pool([FailingSleeper] * 4, num_workers=1, env_concurrency="threads", batch_size=4)
    try:
        envs.reset(seed=0)  # env i's seed is i: env 2 fails
        envs.async_reset()
        ids = None
        got, raised = Counter(), None
        for _ in range(6):
            try:
                obs, _, _, _, info = envs.recv(min_batch=1, max_batch=4, timeout=2.0)
            except SpecialError as err:
                raised = err
                break
            ids = info["env_id"]
            got.update(ids.tolist())
            envs.send(np.zeros(len(ids), np.int64), ids)
        assert raised is not None and "seed 2 failed at step 3" in str(raised)
        assert all(got[e] >= 3 for e in (0, 1, 3)), got
        envs.reset(seed=0)
        envs.step(np.zeros(4, np.int64))
    finally:
        _closed(envs)


def test_a_worker_killed_during_concurrent_resets_costs_its_envs_one_restarted_episode() -> None:
    envs = _pool(
        [lambda: SlowResetEnv(step_s=0.001, reset_s=0.3, every=1000)] * 4,
        num_workers=2,
        env_concurrency="threads",
        start_timeout=30,
    )
    try:
        envs.reset(seed=0)
        envs.reset_async(seed=1)
        time.sleep(0.1)  # every env of both workers is in its 0.3 s reset, on its thread
        import os
        import signal

        os.kill(envs.worker_pids[0], signal.SIGKILL)
        obs, infos = envs.reset_wait()
        assert obs.shape == (4, 1)
        _, _, _, trunc, infos = envs.step(np.zeros(4, np.int64))
        assert envs.restarts == 1
        envs.step(np.zeros(4, np.int64))
    finally:
        _closed(envs)


def test_close_with_envs_asleep_ends_within_its_bound() -> None:
    envs = _pool(
        [lambda: SleepEnv(60.0)] * 4, num_workers=1, env_concurrency="threads", batch_size=4
    )
    envs.async_reset()
    envs.recv()
    envs.send(np.zeros(4, np.int64), np.arange(4))
    time.sleep(0.2)  # every env is inside its 60 s sleep
    t = time.monotonic()
    _closed(envs)
    assert time.monotonic() - t < 3.0


def test_deadlines_hand_out_the_envs_ready_and_keep_the_slow_in_flight() -> None:
    """Envs 0-2 step in 1 ms, env 3 in 300 ms, all on one worker's threads: a 50 ms deadline
    hands out the three fast ones; env 3 comes later, nothing lost."""
    fns = [lambda: SleepEnv(0.001)] * 3 + [lambda: SleepEnv(0.3)]
    envs = _pool(fns, num_workers=1, env_concurrency="threads", batch_size=4)
    try:
        envs.async_reset()
        envs.recv()
        envs.send(np.zeros(4, np.int64), np.arange(4))
        info = envs.recv(min_batch=1, max_batch=4, timeout=0.05)[4]
        assert sorted(info["env_id"].tolist()) == [0, 1, 2]
        envs.send(np.zeros(3, np.int64), info["env_id"])
        slow = []
        deadline = time.monotonic() + 5
        while 3 not in slow and time.monotonic() < deadline:
            info = envs.recv(min_batch=1, max_batch=4, timeout=0.5)[4]
            slow += info["env_id"].tolist()
            fast = [e for e in info["env_id"].tolist() if e != 3]
            if fast:
                envs.send(np.zeros(len(fast), np.int64), fast)
        assert 3 in slow
    finally:
        _closed(envs)


def test_service_stays_fair_with_envs_on_threads() -> None:
    """8 sleeping envs on 2 workers' threads, batches of 2, first ready first: every env is
    served within 10% of the mean."""
    envs = _pool(
        [lambda: SleepEnv(0.002)] * 8, num_workers=2, env_concurrency="threads", batch_size=2
    )
    try:
        envs.async_reset()
        served: Counter[int] = Counter()
        for _ in range(1500):
            ids = envs.recv()[4]["env_id"]
            served.update(ids.tolist())
            envs.send(np.zeros(len(ids), np.int64), ids)
        mean = sum(served.values()) / 8
        assert all(abs(c - mean) <= 0.1 * mean for c in served.values()), served
    finally:
        _closed(envs)


def test_threads_are_for_envs_of_one_callable_each() -> None:
    with pytest.raises(ValueError, match="env_concurrency"):
        rogue_gym.make_vec(4, config=rogue_gym.PAPER_CONFIG, env_concurrency="threads")
    with pytest.raises(ValueError, match="env_concurrency must be"):
        _pool([SleepEnv] * 2, env_concurrency="many")
    envs = _pool([SleepEnv] * 4, num_workers=2, env_concurrency="threads")
    try:
        envs.reset(seed=0)
        envs.step(np.zeros(4, np.int64))
        assert envs.stats().workers[0].env_wait_s > 0, "the envs' sleep counts as waiting"
    finally:
        _closed(envs)


def _policies(pid: int) -> set[int]:
    """The scheduling policies of a worker's own threads, its main thread and those it starts
    (``rg-*``), not those of the libraries it loads (numpy's BLAS pool): 0 normal, 3 batch."""
    out = set()
    for t in os.listdir(f"/proc/{pid}/task"):
        with open(f"/proc/{pid}/task/{t}/comm") as f:
            if t != str(pid) and not f.read().startswith("rg-"):
                continue
        with open(f"/proc/{pid}/task/{t}/sched") as f:
            out |= {int(line.split(":")[1]) for line in f if line.startswith("policy")}
    return out


def test_threaded_workers_run_at_batch_scheduling_and_leave_the_caller_alone() -> None:
    """Their wake-ups do not preempt the caller (docs/performance.md, "Envs that wait");
    serial workers and the caller keep the normal policy."""
    threaded = _pool([SleepEnv] * 4, num_workers=2, env_concurrency="threads")
    serial = _pool([SleepEnv] * 2, num_workers=1)
    try:
        threaded.reset(seed=0)
        serial.reset(seed=0)
        for pid in threaded._core.pool.worker_pids():
            assert _policies(pid) == {os.SCHED_BATCH}
        assert _policies(serial._core.pool.worker_pids()[0]) == {os.SCHED_OTHER}
        assert os.sched_getscheduler(0) == os.SCHED_OTHER
    finally:
        _closed(threaded)
        _closed(serial)


def test_threaded_workers_serve_on_through_many_replacements_and_kills() -> None:
    """Each generation of a threaded worker opens a listener and a waker on its command
    events, which hold a few of each: ten planned replacements and three kills in a row
    (more generations than they hold) and the pool still serves."""
    envs = _pool(
        [lambda: SleepEnv(0.0005)] * 4,
        num_workers=2,
        env_concurrency="threads",
        recycle_after_steps=8,
        start_timeout=30,
    )
    try:
        envs.reset(seed=0)
        for _ in range(50):
            envs.step(np.zeros(4, np.int64))
        assert envs.stats().recycles >= 10
        for _ in range(3):
            os.kill(envs.worker_pids[1], 9)
            envs.step(np.zeros(4, np.int64))
        assert envs.restarts == 3
        obs = envs.step(np.zeros(4, np.int64))[0]
        assert obs.shape == (4, 1)
    finally:
        _closed(envs)
