"""Jit-able stepping (``envs.xla()``): a jitted rollout equals a Python loop of ``step()`` on a
twin pool with the same seed, for the native game and hosted envs, sync and async; the compiled
function runs again from the handle it returned; a killed worker gives the restarted episode
the Python loop gives; a closed pool raises a clear error; a missing or old jax is named."""

from __future__ import annotations

import os
import signal
from collections.abc import Iterator
from typing import Any, Callable

import numpy as np
import pytest

jax = pytest.importorskip("jax")
jnp = pytest.importorskip("jax.numpy")

import rogue_gym.envpool as envpool  # noqa: E402
from rogue_gym import xla  # noqa: E402

from conftest import pid_alive, wait_until  # noqa: E402

T = 40


@pytest.fixture
def pools() -> Iterator[Callable[..., Any]]:
    made: list[Any] = []

    def factory(task_id: str, **kw: Any) -> Any:
        env = envpool.make(task_id, **kw)
        made.append(env)
        return env

    yield factory
    for env in made:
        env.close()


def scan_rollout(step: Callable[..., Any]) -> Callable[..., Any]:
    """A jitted ``lax.scan`` of ``step`` over precomputed actions, keeping what a loop sees."""

    @jax.jit
    def roll(handle: Any, actions: Any) -> Any:
        def body(h: Any, a: Any) -> Any:
            h, (obs, reward, terminated, truncated, info) = step(h, a)
            return h, (obs, reward, terminated, truncated, info["elapsed_step"], info["env_id"])

        return jax.lax.scan(body, handle, actions)

    return roll


def python_rollout(env: Any, actions: np.ndarray) -> tuple[np.ndarray, ...]:
    rows = []
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        rows.append((obs, reward, terminated, truncated, info["elapsed_step"], info["env_id"]))
    return tuple(np.stack(col) for col in zip(*rows))


def assert_same(jitted: tuple[Any, ...], looped: tuple[np.ndarray, ...]) -> None:
    names = ("obs", "reward", "terminated", "truncated", "elapsed_step", "env_id")
    for name, a, b in zip(names, jitted, looped):
        a = np.asarray(a)
        assert a.shape == b.shape, name
        if name == "reward":
            np.testing.assert_allclose(a, b, rtol=1e-6, err_msg=name)
        else:
            np.testing.assert_array_equal(a, b, err_msg=name)


@pytest.mark.parametrize(
    ("task_id", "num_envs", "kw"),
    [
        ("RogueGym-v0", 16, {}),
        ("CartPole-v1", 8, {}),
        ("Acrobot-v1", 4, {"max_episode_steps": 15}),
    ],
)
def test_jitted_rollout_equals_the_python_loop(
    pools: Callable[..., Any], task_id: str, num_envs: int, kw: dict[str, Any]
) -> None:
    env = pools(task_id, num_envs=num_envs, num_threads=2, seed=7, **kw)
    twin = pools(task_id, num_envs=num_envs, num_threads=2, seed=7, **kw)
    handle, _recv, _send, step = env.xla()
    env.reset()
    twin.reset()
    rng = np.random.default_rng(0)
    actions = rng.integers(0, env.action_space.n, (2 * T, num_envs))
    roll = scan_rollout(step)
    handle, first = roll(handle, jnp.asarray(actions[:T], jnp.int32))
    assert_same(first, python_rollout(twin, actions[:T]))
    # The compiled function runs again from the handle it returned, going on where it was.
    handle, second = roll(handle, jnp.asarray(actions[T:], jnp.int32))
    assert_same(second, python_rollout(twin, actions[T:]))
    if task_id != "RogueGym-v0":
        assert np.asarray(second[2]).any() or np.asarray(second[3]).any()  # autoreset covered


def test_box_actions_and_gym_form(pools: Callable[..., Any]) -> None:
    """Pendulum's float32 Box actions travel as raw bytes; ``env_type="gym"`` gives EnvPool's
    four-tuple with ``info["TimeLimit.truncated"]``, as the Python ``step`` does."""
    env = pools("Pendulum-v1", env_type="gym", num_envs=4, num_threads=2, seed=3)
    twin = pools("Pendulum-v1", env_type="gym", num_envs=4, num_threads=2, seed=3)
    handle, recv, send, _step = env.xla()
    np.testing.assert_array_equal(env.reset(), twin.reset())
    actions = np.random.default_rng(1).uniform(-2, 2, (T, 4, 1)).astype(np.float32)

    def body(i: Any, carry: Any) -> Any:
        h, total, cut = carry
        h, (_obs, reward, done, info) = recv(send(h, jnp.asarray(actions)[i]))
        return h, total + reward, cut | info["TimeLimit.truncated"] | done

    zeros = (jnp.zeros(4, jnp.float32), jnp.zeros(4, bool))
    handle, total, _cut = jax.jit(lambda h: jax.lax.fori_loop(0, T, body, (h, *zeros)))(handle)
    expected = np.zeros(4, np.float32)
    for a in actions:
        _obs, reward, _done, info = twin.step(a)
        expected += reward
        assert "TimeLimit.truncated" in info
    np.testing.assert_allclose(np.asarray(total), expected, rtol=1e-5)


def test_async_rollout_equals_the_python_loop(pools: Callable[..., Any]) -> None:
    """batch_size < num_envs: recv by completion order, send by env_id. The order may differ
    between pools, so each env's own trajectory is compared (its k-th action is fixed)."""
    n, b = 8, 4
    plan = np.random.default_rng(2).integers(0, 2, (T, n))
    env = pools("CartPole-v1", num_envs=n, batch_size=b, num_threads=2, seed=5)
    twin = pools("CartPole-v1", num_envs=n, batch_size=b, num_threads=2, seed=5)
    handle, recv, send, _step = env.xla()
    table = jnp.asarray(plan, jnp.int32)

    @jax.jit
    def roll(h: Any) -> Any:
        def body(carry: Any, _: Any) -> Any:
            h, count = carry
            h, (obs, reward, _te, _tr, info) = recv(h)
            ids = info["env_id"]
            h = send(h, table[count[ids], ids], ids)
            return (h, count.at[ids].add(1)), (ids, obs, reward)

        return jax.lax.scan(body, (h, jnp.zeros(n, jnp.int32)), None, length=T)

    env.async_reset()
    _, (ids, obs, reward) = roll(handle)

    twin.async_reset()
    count = np.zeros(n, int)
    mine: dict[int, list[Any]] = {e: [] for e in range(n)}
    theirs: dict[int, list[Any]] = {e: [] for e in range(n)}
    for t in range(T):
        o, r, _te, _tr, info = twin.recv()
        got = info["env_id"]
        twin.send(plan[count[got], got], got)
        count[got] += 1
        for row, e in enumerate(got):
            theirs[int(e)].append((o[row], r[row]))
        for row, e in enumerate(np.asarray(ids[t])):
            mine[int(e)].append((np.asarray(obs[t][row]), float(reward[t][row])))
    compared = 0
    for e in range(n):
        # Service order (first ready first) may favour one worker's envs under load: compare
        # each env's results as far as both runs got.
        k = min(len(mine[e]), len(theirs[e]))
        assert k >= 1, f"env {e} never served: {len(mine[e])} jitted, {len(theirs[e])} looped"
        for i, ((o1, r1), (o2, r2)) in enumerate(zip(mine[e][:k], theirs[e][:k])):
            np.testing.assert_array_equal(o1, o2, err_msg=f"env {e}, result {i}")
            assert r1 == r2, (e, i)
        compared += k
    assert compared >= T * b // 2, compared


def test_killed_worker_gives_the_restarted_episode(pools: Callable[..., Any]) -> None:
    """A worker killed before a jitted rollout: its envs restart and their row says so
    (truncated, elapsed_step 0, reward 0), exactly as the Python loop of the twin sees it."""
    env = pools("CartPole-v1", num_envs=8, num_threads=2, seed=11)
    twin = pools("CartPole-v1", num_envs=8, num_threads=2, seed=11)
    handle, _recv, _send, step = env.xla()
    env.reset()
    twin.reset()
    for pool in (env, twin):
        victim = pool.pool.worker_pids[1]
        os.kill(victim, signal.SIGKILL)
        assert wait_until(lambda v=victim: not pid_alive(v))
    actions = np.zeros((5, 8), np.int64)
    _, jitted = scan_rollout(step)(handle, jnp.asarray(actions, jnp.int32))
    looped = python_rollout(twin, actions)
    assert_same(jitted, looped)
    victims = list(env.pool.envs_of_worker(1))
    assert (
        np.asarray(jitted[3])[0, victims].all() and (np.asarray(jitted[4])[0, victims] == 0).all()
    )
    assert env.pool.restarts == 1


def test_closed_pool_raises_and_does_not_hang(pools: Callable[..., Any]) -> None:
    env = pools("CartPole-v1", num_envs=4, num_threads=1, seed=0)
    handle, _recv, _send, step = env.xla()
    env.reset()
    roll = scan_rollout(step)
    roll(handle, jnp.zeros((2, 4), jnp.int32))[0].block_until_ready()
    env.close()
    with pytest.raises(Exception, match="pool of this xla\\(\\) handle is closed"):
        roll(handle, jnp.zeros((2, 4), jnp.int32))[0].block_until_ready()
    with pytest.raises(Exception, match="closed"):
        env.xla()


def test_bad_input_is_an_error_not_a_crash(pools: Callable[..., Any]) -> None:
    env = pools("CartPole-v1", num_envs=4, num_threads=1, seed=0)
    handle, recv, send, step = env.xla()
    env.reset()
    with pytest.raises(Exception, match="out of range"):
        step(handle, jnp.array([0, 1, 5, 0], jnp.int32))[0].block_until_ready()
    with pytest.raises(Exception, match=r"4 actions|one action per env"):
        step(handle, jnp.array([0, 1], jnp.int32))[0].block_until_ready()
    with pytest.raises(Exception, match="each env once"):
        step(handle, jnp.array([0, 1, 1, 0], jnp.int32), jnp.array([0, 0, 1, 2], jnp.int32))[
            0
        ].block_until_ready()
    # Nothing was lost: a good step goes on.
    _, (obs, *_rest) = step(handle, jnp.array([0, 1, 1, 0], jnp.int32))
    assert np.asarray(obs).shape == (4, 4)


def test_jax_too_old_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    xla.require_jax.cache_clear()
    monkeypatch.setattr(jax, "__version__", "0.4.20")
    try:
        with pytest.raises(ImportError, match=r"jax >= 0\.5\.0"):
            xla.require_jax()
    finally:
        xla.require_jax.cache_clear()
