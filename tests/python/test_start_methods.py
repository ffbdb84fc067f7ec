"""Nothing relies on ``fork``: pools made in processes that multiprocessing starts by
``forkserver`` (CPython 3.14's default on Linux) and by ``spawn`` play what a pool made here
plays, and the package's own use of multiprocessing (``PoolVecEnv(start_method=...)``) accepts
every method."""

from __future__ import annotations

import multiprocessing as mp
import subprocess
import sys

import numpy as np
import pytest
import rogue_gym


def play(steps: int = 30) -> bytes:
    """A native pool and a hosted one, made and stepped in this process: their observations."""
    out = []
    native = rogue_gym.make_vec(4, config="paper", num_workers=2, seed=3)
    try:
        obs, _ = native.reset(seed=3)
        out.append(obs.tobytes())
        for t in range(steps):
            obs, *_ = native.step(np.full(4, t % 11, np.int64))
            out.append(obs.tobytes())
    finally:
        native.close()
    hosted = rogue_gym.make_vec("CartPole-v1", 4, num_workers=2)
    try:
        obs, _ = hosted.reset(seed=3)
        for t in range(steps):
            obs, *_ = hosted.step(np.full(4, t % 2, np.int64))
            out.append(obs.tobytes())
    finally:
        hosted.close()
    return b"".join(out)


def _child(queue: mp.Queue) -> None:
    queue.put(play())


@pytest.mark.parametrize("method", ["forkserver", "spawn"])
def test_pools_made_under_each_start_method_play_the_same(method: str) -> None:
    want = play()
    ctx = mp.get_context(method)
    queue = ctx.Queue()
    proc = ctx.Process(target=_child, args=(queue,))
    proc.start()
    try:
        got = queue.get(timeout=120)
    finally:
        proc.join(timeout=60)
        if proc.is_alive():
            proc.kill()
            proc.join(timeout=10)
    assert proc.exitcode == 0
    assert got == want


def test_the_default_start_method_is_the_interpreters() -> None:
    # 3.14 made forkserver the default on Linux; either way the pool above does not care. Read
    # in a fresh interpreter: a library another test imported (torch's) may have set its own.
    out = subprocess.run(
        [sys.executable, "-c", "import multiprocessing as mp; print(mp.get_start_method())"],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    ).stdout.strip()
    assert out == ("forkserver" if sys.version_info >= (3, 14) else "fork")


def test_poolvecenv_takes_every_start_method_name() -> None:
    sb3 = pytest.importorskip("rogue_gym.sb3")
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym

    for method in ("fork", "forkserver", "spawn"):
        env = sb3.PoolVecEnv([lambda: gym.make("CartPole-v1")] * 2, start_method=method)
        env.close()
    with pytest.raises(ValueError):
        sb3.PoolVecEnv([lambda: gym.make("CartPole-v1")] * 2, start_method="teleport")
