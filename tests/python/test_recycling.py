"""Planned worker replacement for envs that leak (``recycle_after_steps``, ``recycle_above_rss``):
the replacement builds its envs while the worker serves on, the envs' episodes are cut with
``truncated`` and ``worker_recycled``, every call succeeds, no transition is lost, and the
count is kept apart from crash restarts."""

from __future__ import annotations

import functools
import os
import signal
import time

import numpy as np
import pytest
import rogue_gym
from rogue_gym import PoolVectorEnv

from conftest import pid_alive, pool_files, wait_until
from hosted_envs import LeakyEnv


def rss(pid: int) -> int:
    with open(f"/proc/{pid}/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def test_after_steps_workers_are_replaced_and_no_transition_is_lost() -> None:
    """Every step of every env is delivered: its observation counts up by one within an
    episode, and an episode ends only where the worker was replaced, flagged so."""
    fn = functools.partial(LeakyEnv, leak_mib=0)
    envs = PoolVectorEnv([fn] * 4, num_workers=2, recycle_after_steps=30)
    try:
        envs.reset(seed=0)
        first_pids = list(envs.worker_pids)
        expected = np.zeros(4)
        recycled_rows = 0
        for _ in range(100):
            obs, reward, terminated, truncated, infos = envs.step(np.zeros(4, np.int64))
            recycled = infos.get("worker_recycled", np.zeros(4, bool))
            assert (recycled == truncated).all(), "truncated exactly where recycled"
            assert not terminated.any()
            expected = np.where(recycled, 0, expected + 1)
            np.testing.assert_array_equal(obs[:, 0], expected)
            np.testing.assert_array_equal(reward, np.where(recycled, 0.0, 1.0))
            if recycled.any():
                assert infos["worker_restarted"][recycled].all()
            recycled_rows += int(recycled.sum())
        stats = envs.stats()
        # 2 envs a worker, 30 steps a worker: a replacement every 15 calls.
        assert stats.recycles >= 4 and stats.restarts == 0
        assert recycled_rows == 2 * stats.recycles
        assert not set(first_pids) & set(envs.worker_pids)
        for pid in first_pids:
            assert not pid_alive(pid), "the replaced worker is gone"
    finally:
        envs.close()


def test_a_leaking_env_stays_under_the_bound_through_recycle_after_recycle() -> None:
    """16 envs leaking 1 MiB a step each, 4 workers, 200 MiB a worker: until each worker was
    replaced twice over (at most 60 s), no worker's resident memory passes the bound, so the
    pool's total stays under 4 x 200 MiB, and every call succeeds."""
    bound = 200 << 20
    envs = PoolVectorEnv([LeakyEnv] * 16, num_workers=4, recycle_above_rss=bound)
    try:
        envs.reset(seed=0)
        peak_worker = peak_total = calls = 0
        t0 = time.monotonic()
        while time.monotonic() - t0 < 60 and (calls % 20 or envs.stats().recycles < 8):
            envs.step(np.zeros(16, np.int64))
            calls += 1
            sizes = [rss(p) for p in envs.worker_pids]
            peak_worker = max(peak_worker, *sizes)
            peak_total = max(peak_total, sum(sizes))
        stats = envs.stats()
        print(
            f"calls {calls}, recycles {stats.recycles}, peak worker {peak_worker >> 20} MiB, "
            f"peak total {peak_total >> 20} MiB, {time.monotonic() - t0:.1f} s"
        )
        assert stats.recycles >= 8 and stats.restarts == 0
        assert peak_worker <= bound and peak_total <= 4 * bound
    finally:
        envs.close()


def test_recycling_in_the_async_api_and_the_native_game() -> None:
    envs = rogue_gym.make_vec(
        8, config="paper", num_workers=2, batch_size=4, recycle_after_steps=40, seed=1
    )
    try:
        envs.async_reset()
        recycled_envs: set[int] = set()
        for _ in range(60):
            obs, reward, terminated, truncated, infos = envs.recv()
            if "worker_recycled" in infos:
                rows = infos["worker_recycled"]
                assert truncated[rows].all()
                recycled_envs |= {int(e) for e in infos["env_id"][rows]}
            envs.send(np.zeros(4, np.int64), infos["env_id"])
        assert recycled_envs == set(range(8))
        assert envs.stats().recycles >= 2 and envs.stats().restarts == 0
    finally:
        envs.close()


def test_a_successor_that_fails_leaves_the_worker_serving(tmp_path) -> None:
    """The replacement cannot build its envs: it is dropped, the worker serves on (no call
    fails), and the statistics say why."""
    refuse = tmp_path / "refuse"
    fn = functools.partial(LeakyEnv, leak_mib=0, refuse_if=str(refuse))
    envs = PoolVectorEnv([fn] * 2, num_workers=1, recycle_after_steps=5)
    try:
        envs.reset(seed=0)
        refuse.touch()
        pid = envs.worker_pids[0]
        for _ in range(40):
            obs, *_ = envs.step(np.zeros(2, np.int64))
        assert envs.worker_pids == [pid] and obs[0, 0] == 40
        stats = envs.stats()
        assert stats.recycles == 0 and stats.restarts == 0
        assert "successor of worker 0" in (stats.workers[0].last_failure or "")
    finally:
        envs.close()


def test_bad_recycling_options_are_refused() -> None:
    with pytest.raises(ValueError, match="recycle_after_steps"):
        PoolVectorEnv([LeakyEnv] * 2, recycle_after_steps=0)
    with pytest.raises(ValueError, match="recycle_above_rss"):
        rogue_gym.make_vec(2, config="paper", recycle_above_rss=-1)


def successors(pool_name: str) -> list[int]:
    """Pids of this pool's successor processes (workers started with ``--successor``)."""
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/cmdline", "rb") as f:
                args = f.read().split(b"\0")
        except OSError:
            continue
        ours = b"--successor" in args and any(pool_name.encode() in a for a in args)
        if ours and pid_alive(int(entry)):
            found.append(int(entry))
    return found


def _building(envs: PoolVectorEnv, steps: int) -> int:
    """Step until a successor is building its envs; its pid."""
    for _ in range(steps):
        envs.step(np.zeros(envs.num_envs, np.int64))
        found = successors(envs.pool_name)
        if found:
            return found[0]
    raise AssertionError("no successor was started")


SLOW = functools.partial(LeakyEnv, leak_mib=0, build_s=1.0)


def test_a_worker_killed_while_its_successor_builds_is_restarted_and_the_successor_dropped() -> (
    None
):
    envs = PoolVectorEnv([SLOW] * 2, num_workers=1, recycle_after_steps=40)
    try:
        envs.reset(seed=0)
        successor = _building(envs, 30)
        os.kill(envs.worker_pids[0], signal.SIGKILL)
        _, _, _, truncated, infos = envs.step(np.zeros(2, np.int64))
        assert truncated.all() and infos["worker_restarted"].all()
        assert "worker_recycled" not in infos
        assert wait_until(lambda: not pid_alive(successor))
        for _ in range(5):
            envs.step(np.zeros(2, np.int64))
        stats = envs.stats()
        assert stats.restarts == 1 and stats.recycles == 0
    finally:
        envs.close()


def test_a_successor_killed_while_it_builds_is_replaced_later_and_no_call_fails() -> None:
    """The successor dies (SIGKILL): the worker serves on past its bound; after a pause of half
    of start_timeout a new successor takes over."""
    envs = PoolVectorEnv([SLOW] * 2, num_workers=1, recycle_after_steps=40, start_timeout=4.0)
    try:
        envs.reset(seed=0)
        os.kill(_building(envs, 30), signal.SIGKILL)
        deadline = time.monotonic() + 20
        while envs.stats().recycles == 0 and time.monotonic() < deadline:
            envs.step(np.zeros(2, np.int64))
            time.sleep(0.01)
        stats = envs.stats()
        assert stats.recycles == 1 and stats.restarts == 0
        assert "exited while building" in (stats.workers[0].last_failure or "")
    finally:
        envs.close()


def test_close_while_a_successor_builds_leaves_nothing() -> None:
    envs = PoolVectorEnv([SLOW] * 2, num_workers=1, recycle_after_steps=40)
    name = envs.pool_name
    envs.reset(seed=0)
    successor = _building(envs, 30)
    workers = list(envs.worker_pids)
    envs.close()
    assert wait_until(lambda: not pid_alive(successor) and not any(map(pid_alive, workers)))
    assert wait_until(lambda: not pool_files(name)), pool_files(name)
