"""Shared fixtures: envs that are always closed, leak checks for pools, SIGINT delivery, a
time limit on every test, and SB3's log folders kept out of the shared temporary directory."""

from __future__ import annotations

import os
import signal
import tempfile
import time
from collections.abc import Iterator
from typing import Any, Callable

import pytest
import rogue_gym

PAPER = rogue_gym.PAPER_CONFIG

#: Seconds any one test may run before pytest-timeout fails it and dumps every thread's stack
#: (a hung test must never hold up the suite, or CI's 90 minutes).
TEST_TIMEOUT_S = 300


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Give every test without its own ``@pytest.mark.timeout`` the suite's time limit."""
    for item in items:
        if item.get_closest_marker("timeout") is None:
            item.add_marker(pytest.mark.timeout(TEST_TIMEOUT_S))


@pytest.fixture(autouse=True, scope="session")
def _sb3_log_folder() -> Iterator[None]:
    """SB3 makes a log folder for every model set up without one, under the system's
    temporary directory (``SB3-<date and time>``, left behind); the suite's go to a private
    folder of its own (``SB3_LOGDIR``), removed when the suite ends."""
    old = os.environ.get("SB3_LOGDIR")
    with tempfile.TemporaryDirectory(prefix="rogue-gym-sb3-") as folder:
        os.environ["SB3_LOGDIR"] = folder
        try:
            yield
        finally:
            if old is None:
                os.environ.pop("SB3_LOGDIR", None)
            else:
                os.environ["SB3_LOGDIR"] = old


@pytest.fixture
def sigint_handler() -> Iterator[None]:
    """Python's own SIGINT handler for the test, whatever the suite was started with.

    A process started as a background job of a non-interactive shell (CI, ``cmd &`` in a script)
    inherits SIGINT *ignored*, and Python then installs no handler: a SIGINT, Ctrl-C included,
    is dropped. Tests of Ctrl-C handling install the handler themselves and put the old one
    back afterwards.
    """
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def pid_alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            state = f.read().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return False
    return state != "Z"


def pool_files(name: str) -> list[str]:
    """Files of pool ``name`` left in /dev/shm and in the runtime directory."""
    out = [f"/dev/shm/{f}" for f in os.listdir("/dev/shm") if f.startswith(f"{name}_")]
    base = rogue_gym._native.default_runtime_dir()
    if os.path.isdir(base):
        out += [f"{base}/{f}" for f in os.listdir(base) if f == name or f.startswith(f"{name}.")]
    return out


def wait_until(cond: Callable[[], bool], timeout: float = 5.0) -> bool:
    """Poll ``cond`` until it holds or ``timeout`` seconds pass."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.02)
    return cond()


@pytest.fixture
def make_vec() -> Iterator[Callable[..., Any]]:
    """``make_vec(**kw)`` building pools that are closed (and checked for leaks) at teardown."""
    made: list[Any] = []

    def factory(num_envs: int = 4, **kw: Any) -> Any:
        kw.setdefault("config", PAPER)
        kw.setdefault("num_workers", 2)
        kw.setdefault("seed", 0)
        env = rogue_gym.make_vec(num_envs, **kw)
        made.append(env)
        return env

    yield factory
    for env in made:
        core = env._core
        pids = core.worker_pids
        name = core.name
        env.close()
        assert wait_until(lambda pids=pids: not any(pid_alive(p) for p in pids)), (
            "workers left running"
        )
        assert pool_files(name) == [], "pool files left behind"


@pytest.fixture
def make_sb3() -> Iterator[Callable[..., Any]]:
    """``make_sb3(**kw)`` building SB3 pools that are closed at teardown."""
    pytest.importorskip("stable_baselines3")
    from rogue_gym.sb3 import RogueVecEnv

    made: list[Any] = []

    def factory(num_envs: int = 4, **kw: Any) -> Any:
        kw.setdefault("config", PAPER)
        kw.setdefault("num_workers", 2)
        kw.setdefault("seed", 0)
        env = RogueVecEnv(num_envs, **kw)
        made.append(env)
        return env

    yield factory
    for env in made:
        env.close()


def _cartpole() -> Any:
    import gymnasium as gym

    return gym.make("CartPole-v1")


def _cartpole_vector(n: int) -> Any:
    """``n`` CartPoles in a ``SyncVectorEnv`` (NEXT_STEP): a vector env per worker block."""
    from gymnasium.vector import SyncVectorEnv

    return SyncVectorEnv([_cartpole] * n)


def _cartpole_vector_same_step(n: int) -> Any:
    """As :func:`_cartpole_vector`, autoresetting in SAME_STEP (what SB3's facade needs)."""
    from gymnasium.vector import AutoresetMode, SyncVectorEnv

    return SyncVectorEnv([_cartpole] * n, autoreset_mode=AutoresetMode.SAME_STEP)


@pytest.fixture
def make_kind() -> Iterator[Callable[..., Any]]:
    """``make_kind(kind, facade="gymnasium", num_envs=4, **kw)``: a pool of the native game
    (paper config, seed 0), of hosted CartPole or of CartPole in one ``SyncVectorEnv`` per
    worker (``"vector"``), 2 workers, as a gymnasium vector env or an SB3 ``VecEnv``; closed at teardown and checked for leftover workers and files. For the
    tests of behaviour every kind shares."""
    made: list[Any] = []

    def factory(kind: str, facade: str = "gymnasium", num_envs: int = 4, **kw: Any) -> Any:
        kw.setdefault("num_workers", 2)
        if facade == "sb3":
            pytest.importorskip("stable_baselines3")
            from rogue_gym.sb3 import PoolVecEnv, RogueVecEnv

        if kind == "native":
            kw.setdefault("config", PAPER)
            kw.setdefault("seed", 0)
            env = (RogueVecEnv if facade == "sb3" else rogue_gym.RogueVectorEnv)(num_envs, **kw)
        elif kind == "hosted":
            fns = [_cartpole] * num_envs
            env = (PoolVecEnv if facade == "sb3" else rogue_gym.PoolVectorEnv)(fns, **kw)
        elif kind == "vector":
            if facade == "sb3":
                env = PoolVecEnv.from_vector_env(_cartpole_vector_same_step, num_envs, **kw)
            else:
                env = rogue_gym.PoolVectorEnv.from_vector_env(_cartpole_vector, num_envs, **kw)
        else:
            raise ValueError(f"unknown kind {kind!r}")
        made.append(env)
        return env

    yield factory
    for env in made:
        pids, name = env.worker_pids, (env.venv if hasattr(env, "venv") else env).pool_name
        env.close()
        assert wait_until(lambda pids=pids: not any(pid_alive(p) for p in pids)), (
            "workers left running"
        )
        assert pool_files(name) == [], "pool files left behind"
