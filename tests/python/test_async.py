"""The async API env by env: any batch size, any envs sent, first ready first served, deadlines,
fair service (also beside a CPU hog), and trajectories that depend only on seeds and actions."""

from __future__ import annotations

import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import rogue_gym


def _pool(num_envs: int, num_workers: int, batch_size: int, **kw):
    return rogue_gym.make_vec(
        "RogueGym-v0",
        num_envs=num_envs,
        num_workers=num_workers,
        batch_size=batch_size,
        max_steps=kw.pop("max_steps", 40),
        **kw,
    )


def test_any_batch_size_any_envs_and_clear_errors() -> None:
    env = _pool(5, 2, 3)  # blocks of 3 and 2: a batch is not a whole number of blocks
    try:
        env.async_reset(seed=1)
        obs, _, _, _, info = env.recv()
        assert obs.shape[0] == 3 and len(set(info["env_id"].tolist())) == 3
        first = info["env_id"]
        env.send(np.zeros(1, np.int64), first[:1])  # one env of a worker block
        with pytest.raises(RuntimeError, match=f"env {first[0]} is in flight"):
            env.send(np.zeros(1, np.int64), first[:1])
        with pytest.raises(RuntimeError, match="appears twice"):
            env.send(np.zeros(2, np.int64), [first[1], first[1]])
        rest = [e for e in range(5) if e not in first.tolist()]
        # Not received yet (still stepping, or ready and waiting): refused, with the fix.
        with pytest.raises(RuntimeError, match=f"env {rest[0]} .*recv\\(\\) it before sending"):
            env.send(np.zeros(1, np.int64), rest[:1])
        with pytest.raises(ValueError, match="action 99 is out of range"):
            env.send(np.array([99]), first[1:2])
        # max_batch: no more than asked; min_batch with no timeout: what is ready then.
        obs, _, _, _, info = env.recv(min_batch=1, max_batch=2, timeout=5.0)
        assert 1 <= obs.shape[0] <= 2
    finally:
        env.close()


def test_a_deadline_returns_what_is_ready_or_times_out_losing_nothing() -> None:
    def slow_reset_env():
        import gymnasium as gym

        class SlowReset(gym.Env):
            observation_space = gym.spaces.Box(0, 1, (2,), np.float32)
            action_space = gym.spaces.Discrete(2)

            def reset(self, *, seed=None, options=None):
                super().reset(seed=seed)
                time.sleep(0.3 if self.np_random.random() < 2 else 0)
                return np.zeros(2, np.float32), {}

            def step(self, action):
                return np.ones(2, np.float32), 1.0, False, False, {}

        return SlowReset()

    env = rogue_gym.PoolVectorEnv([slow_reset_env] * 2, num_workers=2, batch_size=2)
    try:
        env.async_reset(seed=0)
        t0 = time.monotonic()
        with pytest.raises(TimeoutError, match="nothing is lost"):
            env.recv(min_batch=1, timeout=0.05)
        assert time.monotonic() - t0 < 0.25
        obs, *_, info = env.recv(min_batch=2, timeout=5.0)  # the results were kept
        assert sorted(info["env_id"].tolist()) == [0, 1]
        env.send(np.zeros(2, np.int64), [0, 1])
        # recv's arguments are checked as strictly as send's: nothing is taken by a bad call.
        for bad, match in (
            ({"min_batch": 2, "max_batch": 1}, "must not exceed max_batch"),
            ({"max_batch": 3}, "between 1 and num_envs"),
            ({"min_batch": 0}, "between 1 and num_envs"),
            ({"timeout": -1.0}, "non-negative"),
        ):
            with pytest.raises(ValueError, match=match):
                env.recv(**bad)
        obs, r, *_ = env.recv(min_batch=2, max_batch=2, timeout=5.0)
        assert r.tolist() == [1.0, 1.0]
        env.send(np.zeros(1, np.int64), np.array([1], np.int32))  # any integer array of ids
        with pytest.raises(TypeError, match="env_id must be integers"):
            env.send(np.zeros(1, np.int64), np.array([0.0]))
        _, _, _, _, info = env.recv(min_batch=1, max_batch=1, timeout=5.0)
        assert info["env_id"].tolist() == [1]
    finally:
        env.close()


def _served(env, recvs: int) -> Counter:
    count: Counter = Counter()
    env.async_reset(seed=0)
    for _ in range(recvs):
        _, _, _, _, info = env.recv()
        ids = info["env_id"]
        count.update(ids.tolist())
        env.send(np.zeros(len(ids), np.int64), ids)
    return count


def _assert_fair(count: Counter, n: int) -> None:
    mean = sum(count.values()) / n
    worst = max(abs(count[e] - mean) / mean for e in range(n))
    assert worst <= 0.10, f"per-env recvs {sorted(count.items())}: {worst:.1%} off the mean"


def test_every_env_is_served_evenly() -> None:
    env = _pool(8, 4, 2, max_steps=10_000)
    try:
        _assert_fair(_served(env, 10_000), 8)
    finally:
        env.close()


def test_every_env_is_served_evenly_beside_a_cpu_hog() -> None:
    hog = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        env = _pool(8, 4, 2, max_steps=10_000)
        try:
            _assert_fair(_served(env, 10_000), 8)
        finally:
            env.close()
    finally:
        hog.kill()
        hog.wait(timeout=10)


def _trajectories(env, steps: int, order_seed: int) -> dict[int, list[bytes]]:
    """Every env's observations, each env stepping with its own actions (a function of env
    and step), whatever batches and order the pool serves them in; sends random subsets."""
    rng = np.random.default_rng(order_seed)
    n = env.num_envs
    seen: dict[int, list[bytes]] = {e: [] for e in range(n)}
    held: list[int] = []
    env.async_reset(seed=5)
    while min(len(v) for v in seen.values()) <= steps:
        obs, _, _, _, info = env.recv()
        for r, e in enumerate(info["env_id"].tolist()):
            seen[e].append(obs[r].tobytes())
            held.append(e)
        # Send a random part of what is held (keeping enough in flight for the next recv).
        rng.shuffle(held)
        k = max(len(held) - (n - env.batch_size), int(rng.integers(1, len(held) + 1)))
        go, held = held[:k], held[k:]
        acts = np.array([(e * 7 + len(seen[e])) % 11 for e in go], np.int64)
        env.send(acts, go)
    return {e: v[: steps + 1] for e, v in seen.items()}


@pytest.mark.parametrize(("workers", "batch"), [(1, 6), (3, 1), (2, 4)])
def test_each_envs_trajectory_is_its_own_whatever_the_layout(workers: int, batch: int) -> None:
    ref_env = _pool(6, 1, 6)
    try:
        want = _trajectories(ref_env, 25, order_seed=0)
    finally:
        ref_env.close()
    env = _pool(6, workers, batch)
    try:
        got = _trajectories(env, 25, order_seed=workers)
    finally:
        env.close()
    assert got == want


@pytest.mark.parametrize("mode", ["next_step", "same_step"])
def test_render_after_send_and_recv_shows_the_envs_as_they_are(mode: str) -> None:
    """The native game's screens are rebuilt by replay: after async steps (episodes ending on
    the way) ``render()`` equals that of a sync twin stepped with the same actions."""
    from gymnasium.vector import AutoresetMode

    am = AutoresetMode.SAME_STEP if mode == "same_step" else AutoresetMode.NEXT_STEP
    kw = dict(max_steps=7, render_mode="ansi", autoreset_mode=am)
    steps = 17  # crosses two episode ends

    def action(e: int, t: int) -> int:
        return (3 * e + t) % 11

    twin = rogue_gym.make_vec("RogueGym-v0", num_envs=4, num_workers=1, **kw)
    env = rogue_gym.make_vec("RogueGym-v0", num_envs=4, num_workers=2, batch_size=2, **kw)
    try:
        twin.reset(seed=9)
        for t in range(steps):
            twin.step(np.array([action(e, t) for e in range(4)]))
        env.async_reset(seed=9)
        done = np.zeros(4, int)  # steps sent to each env
        outstanding = 4
        while outstanding:
            _, _, _, _, info = env.recv(min_batch=1, max_batch=outstanding)
            outstanding -= len(info["env_id"])
            go = [int(e) for e in info["env_id"] if done[e] < steps]
            if go:
                env.send(np.array([action(e, done[e]) for e in go]), go)
                done[go] += 1
                outstanding += len(go)
        assert env.render() == twin.render()
    finally:
        env.close()
        twin.close()


def test_recv_hands_out_rows_in_place_until_the_next_recv() -> None:
    """Two halves on one worker: each recv is a view of the rows the worker wrote in place
    (observations and infos), unchanged while the worker steps those envs again after the
    send, until the next recv; with copy=True they are the caller's own."""
    env = _pool(8, 1, 4)
    kept = _pool(8, 1, 4, copy=True)
    try:
        for pool in (env, kept):
            pool.async_reset(seed=3)
        views = 0
        for t in range(30):
            obs, reward, _te, _tr, infos = env.recv()
            obs2, reward2, *_rest, infos2 = kept.recv()
            assert np.array_equal(obs, obs2) and np.array_equal(reward, reward2), t
            assert np.array_equal(infos["env_id"], infos2["env_id"])
            shared = any(np.shares_memory(obs, s) for s in env._core.slots)
            views += shared
            assert not any(np.shares_memory(obs2, s) for s in kept._core.slots)
            snapshot, length = obs.copy(), infos["episode_length"].copy()
            acts = np.full(len(infos["env_id"]), t % 11, np.int64)
            env.send(acts, infos["env_id"])
            kept.send(acts, infos2["env_id"])
            time.sleep(0.002)  # the worker steps those envs meanwhile
            assert np.array_equal(obs, snapshot), "a view changed before the next recv"
            assert np.array_equal(infos["episode_length"], length)
        assert views >= 26, f"{views} of 30 recvs were views (all but the reset's two)"
    finally:
        env.close()
        kept.close()


def test_the_double_buffering_example_runs() -> None:
    """python/examples/double_buffer.py (the CleanRL-shaped loop of two halves) runs."""
    pytest.importorskip("torch")  # the example's policy is a torch network
    script = Path(__file__).resolve().parents[2] / "python" / "examples" / "double_buffer.py"
    out = subprocess.run(
        [sys.executable, str(script), "--num-envs", "8", "--total-steps", "4000"],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    ).stdout
    assert "4000 steps" in out and "steps/s" in out, out
