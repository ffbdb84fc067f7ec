"""What must hold on every platform the wheel is built for: the tests that
``scripts/aarch64.sh test`` runs under emulation on the aarch64 wheel (they run here, natively,
with the rest of the suite). The native pool (sync, async with ``batch_size < num_envs``), a
hosted gymnasium env against ``SyncVectorEnv``, a worker killed mid-step, the shared-memory
budget, determinism across layouts, and a stress test of the shared-memory handshakes.

Every bound is generous: under qemu-user a worker's Python start-up takes seconds.
"""

from __future__ import annotations

import errno
import os
import signal
import time
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import rogue_gym

from conftest import pid_alive, pool_files, wait_until

#: Bounds for slow (emulated) machines: a worker's start-up, a step.
SLOW = {"start_timeout": 180.0, "step_timeout": 120.0}


def _native(num_envs: int, workers: int, **kw: Any) -> Any:
    return rogue_gym.make_vec(num_envs, config="paper", num_workers=workers, seed=3, **SLOW, **kw)


def _closed(env: Any) -> None:
    pids, name = env.worker_pids, env.pool_name
    env.close()
    assert wait_until(lambda: not any(pid_alive(p) for p in pids), 30), "workers left running"
    assert pool_files(name) == [], "pool files left behind"


def _digest(num_envs: int, workers: int, steps: int) -> list[bytes]:
    env = _native(num_envs, workers)
    try:
        rng = np.random.default_rng(7)
        obs, _ = env.reset()
        out = [obs.tobytes()]
        for _ in range(steps):
            obs, rew, term, trunc, _ = env.step(rng.integers(0, 11, num_envs))
            out.append(obs.tobytes() + rew.tobytes() + term.tobytes() + trunc.tobytes())
        return out
    finally:
        _closed(env)


def test_the_native_pool_steps_and_serves_envs_async() -> None:
    env = _native(6, 2, batch_size=3)
    try:
        obs, infos = env.reset()
        assert obs.shape == (6, 17, 16, 32) and obs.dtype == np.uint8
        assert obs.any(axis=(1, 2, 3)).all(), "every env shows its dungeon"
        for _ in range(20):
            obs, rew, term, trunc, infos = env.step(np.full(6, 1, np.int64))
            assert rew.dtype == np.float64 and term.dtype == np.bool_
        env.async_reset()
        served = np.zeros(6, int)
        for _ in range(8):
            obs, rew, term, trunc, infos = env.recv()
            ids = infos["env_id"]
            assert len(ids) == 3 and obs.shape == (3, 17, 16, 32)
            served[ids] += 1
            env.send(np.full(3, 2, np.int64), ids)
        assert served.min() >= 1, f"every env is served: {served}"
    finally:
        _closed(env)


@pytest.mark.parametrize("streaming", [None, True])
def test_a_hosted_env_matches_sync_vector_env(streaming: Any) -> None:
    def cartpole() -> gym.Env:
        return gym.make("CartPole-v1")

    pool = rogue_gym.PoolVectorEnv(
        [cartpole] * 4, num_workers=2, streaming_stores=streaming, **SLOW
    )
    ref = gym.vector.SyncVectorEnv([cartpole] * 4)
    try:
        a, _ = pool.reset(seed=11)
        b, _ = ref.reset(seed=11)
        np.testing.assert_array_equal(a, b)
        rng = np.random.default_rng(0)
        for _ in range(60):
            act = rng.integers(0, 2, 4)
            got, want = pool.step(act), ref.step(act)
            for x, y in zip(got[:4], want[:4]):
                np.testing.assert_array_equal(x, y)
    finally:
        ref.close()
        _closed(pool)


def test_a_worker_killed_mid_step_is_restarted_and_its_envs_flagged() -> None:
    env = _native(4, 2)
    try:
        env.reset()
        victim = env.worker_pids[1]
        # Stopped first, so that the step is surely in its hands when it dies.
        os.kill(victim, signal.SIGSTOP)
        env.step_async(np.zeros(4, np.int64))
        os.kill(victim, signal.SIGKILL)
        _, rew, _, trunc, infos = env.step_wait()
        restarted = infos["worker_restarted"]
        assert list(restarted) == [False, False, True, True]
        assert trunc[2:].all() and (rew[2:] == 0).all()
        assert env.worker_pids[1] != victim and env.restarts == 1
        for _ in range(5):
            env.step(np.ones(4, np.int64))
    finally:
        _closed(env)


class _WideActions(gym.Env):  # type: ignore[type-arg]
    """256 KiB of actions per env: they travel in the workers' command channels, the one
    part of a pool in /dev/shm that grows with its envs (rows are in the pool's own buffers)."""

    observation_space = gym.spaces.Box(0, 255, (4,), np.uint8)
    action_space = gym.spaces.Box(0, 1, (1 << 16,), np.float32)

    def reset(self, seed: Any = None, options: Any = None) -> Any:
        return np.zeros(4, np.uint8), {}

    def step(self, action: Any) -> Any:
        return np.zeros(4, np.uint8), 0.0, False, False, {}


def _wide(num_envs: int, workers: int) -> Any:
    return rogue_gym.PoolVectorEnv([_WideActions] * num_envs, num_workers=workers, **SLOW)


def _too_big() -> None:
    """A pool whose workers' channels need a quarter more than /dev/shm's free space:
    ``OSError(ENOSPC)`` at once, naming /dev/shm and the fixes. (Its batch buffer is a memory
    file, not in /dev/shm: docs/containers.md.)"""
    need = []
    for n in (2, 4):
        env = _wide(n, 1)
        need.append(env.stats().shm_bytes)
        env.close()
    per_env = (need[1] - need[0]) / 2
    assert per_env > 0, need
    st = os.statvfs("/dev/shm")
    n = int(st.f_bavail * st.f_frsize / per_env * 1.25) + 2
    t = time.monotonic()
    try:
        _wide(n, 2)
    except OSError as err:
        assert err.errno == errno.ENOSPC, err
        assert "/dev/shm" in str(err) and "fewer envs" in str(err), err
        assert time.monotonic() - t < 10
    else:
        raise AssertionError(f"a pool of {n} envs was built")


def test_a_pool_larger_than_dev_shm_fails_at_once_with_the_fixes() -> None:
    st = os.statvfs("/dev/shm")
    if st.f_blocks * st.f_frsize <= 2**30:
        _too_big()
        return
    # A machine's large /dev/shm: the same in a 64 MiB one of our own.
    from test_shm import _in_small_shm, _ok

    here = os.path.dirname(os.path.abspath(__file__))
    _ok(
        _in_small_shm(
            f"import sys; sys.path.insert(0, {here!r}); import test_platform; test_platform._too_big()"
        )
    )


def test_trajectories_are_the_same_with_one_or_two_workers() -> None:
    assert _digest(6, 1, 40) == _digest(6, 2, 40)


def _played(streaming: Any) -> list[bytes]:
    """Everything a caller reads of a short SAME_STEP run: sync steps (final observations,
    episode ends every 5 steps), a partial reset, then async recv/send rounds."""
    env = _native(6, 2, max_steps=5, autoreset_mode="same_step", streaming_stores=streaming)
    try:
        rng = np.random.default_rng(5)
        obs, _ = env.reset()
        out = [obs.tobytes()]
        for t in range(14):
            obs, rew, term, trunc, infos = env.step(rng.integers(0, 11, 6))
            out.append(obs.tobytes() + rew.tobytes() + term.tobytes() + trunc.tobytes())
            if "final_obs" in infos:
                done = np.flatnonzero(infos["_final_obs"])
                out += [infos["final_obs"][i].tobytes() for i in done]
            if t == 8:
                obs, _ = env.reset(options={"reset_mask": np.array([1, 0, 0, 1, 1, 0], bool)})
                out.append(obs.tobytes())
        env.async_reset()
        for _ in range(6):
            obs, rew, term, trunc, infos = env.recv()
            ids = infos["env_id"]
            order = np.argsort(ids)  # rows come in completion order
            out.append(ids[order].tobytes() + obs[order].tobytes() + rew[order].tobytes())
            env.send(rng.integers(0, 11, len(ids))[ids], ids)
        return out
    finally:
        _closed(env)


def test_streaming_stores_change_nothing_a_caller_reads() -> None:
    plain = _played(False)
    assert len(plain) > 20
    assert _played(True) == plain
    assert _played(None) == plain  # by the batch's size: plain here
    with pytest.raises(ValueError, match="streaming_stores"):
        _native(2, 1, streaming_stores="yes")


def test_rows_stay_whole_through_many_steps_and_kills() -> None:
    """Each row's observation and its columns come from one step of one env. The toy env's
    observation is its 64-bit state (byte ``k`` xor ``k``); its columns hold values derived from
    the same state (the state modulo 1000; after a step, the reward ``state % 7 - 3`` and
    ``terminated`` iff 31 divides it) and its step count twice (an info value and the episode
    length). A missing barrier between a worker's writes and its answer, or between the answer
    and the caller's reads, shows as a row whose parts disagree. Four workers on the machine's
    cores, a worker killed every 25 steps, 600 steps."""
    from rogue_gym.front.vector_env import FrontVectorEnv

    from test_kind_spec import ToyKind  # the pool's deterministic Rust test env, as a kind

    rng = np.random.default_rng(1)
    env = FrontVectorEnv(ToyKind(8, obs_shape=(8,), num_workers=4))
    try:
        env.reset(seed=0)
        kills = stepped = 0
        for step in range(600):
            if step % 25 == 12:
                os.kill(env.worker_pids[int(rng.integers(0, 4))], signal.SIGKILL)
                kills += 1
            obs, rew, term, trunc, infos = env.step(rng.integers(0, 3, 8))
            state = np.zeros(8, np.uint64)
            for k in range(8):
                state |= (obs[:, k] ^ np.uint8(k)).astype(np.uint64) << np.uint64(8 * k)
            cols = env._core.cols[env._core.state.slot]
            where = f"step {step}"
            np.testing.assert_array_equal(cols["info_int"][0], cols["episode_length"], where)
            np.testing.assert_array_equal(cols["info_int"][1], state % np.uint64(1000), where)
            after = (cols["episode_length"] > 0) & ~cols["restarted"]
            np.testing.assert_array_equal(
                rew[after], (state[after] % np.uint64(7)).astype(np.float64) - 3, where
            )
            np.testing.assert_array_equal(term[after], state[after] % np.uint64(31) == 0, where)
            stepped += int(after.sum())
        assert kills == 24 and env.restarts >= kills and stepped > 3000
    finally:
        _closed(env)


def _cores_of(pid: int) -> set[int]:
    with open(f"/proc/{pid}/status") as f:
        line = next(x for x in f if x.startswith("Cpus_allowed_list:"))
    cores: set[int] = set()
    for part in line.split(":", 1)[1].strip().split(","):
        lo, _, hi = part.partition("-")
        cores.update(range(int(lo), int(hi or lo) + 1))
    return cores


def test_cpu_affinity_pins_each_worker_to_its_core_and_is_off_by_default() -> None:
    usable = sorted(os.sched_getaffinity(0))
    pinned = _native(4, 2, cpu_affinity=1)
    free = _native(4, 2)
    try:
        for k, pid in enumerate(pinned.worker_pids):
            assert _cores_of(pid) == {usable[(1 + k) % len(usable)]}, k
        for pid in free.worker_pids:
            assert _cores_of(pid) == set(usable)
        pinned.reset()
        pinned.step(np.ones(4, np.int64))
    finally:
        _closed(pinned)
        _closed(free)
    with pytest.raises(ValueError, match="cpu_affinity"):
        _native(4, 2, cpu_affinity=-1)
