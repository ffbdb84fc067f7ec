"""Vector envs hosted one per worker block (``PoolVectorEnv.from_vector_env``): the same
outputs as the vector env itself in one process, whatever the worker layout; partial resets,
env exceptions, bad vector env functions, a killed worker, calls."""

from __future__ import annotations

import functools
from collections.abc import Iterator
from typing import Any, Callable

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv
from rogue_gym import PoolVectorEnv
from rogue_gym.front import leases

from hosted_envs import CountingEnv, InfoEnv, NestedEnv, RaisingEnv, SpecialError
from test_hosted import assert_killed_worker_restarts, assert_tree_equal, run_both, tracked


def cartpole() -> gym.Env:
    return gym.make("CartPole-v1")


def sync_of(make: Callable[[], gym.Env], **kw: Any) -> Callable[[int], SyncVectorEnv]:
    """A vector env function: ``n`` envs of ``make`` in a ``SyncVectorEnv``."""
    return lambda n: SyncVectorEnv([make] * n, **kw)


@pytest.fixture
def hosted() -> Iterator[Callable[..., PoolVectorEnv]]:
    """``hosted(vector_env_fn, num_envs, **kw)``: closed at teardown, checked for leftover
    files and workers."""
    yield from tracked(PoolVectorEnv.from_vector_env)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize("workers", [1, 3])
@pytest.mark.parametrize("make", [cartpole, NestedEnv, InfoEnv], ids=["cartpole", "nested", "info"])
def test_outputs_equal_the_vector_env_in_one_process(hosted, make, workers, mode) -> None:
    """Observations, rewards, flags and infos (keys, dtypes, masks, nesting; SAME_STEP's
    ``final_obs`` and ``final_info``) over episode ends, for Discrete and Dict/Tuple actions,
    with one block and with three uneven ones."""
    ours = hosted(sync_of(make, autoreset_mode=mode), 7, num_workers=workers, autoreset_mode=mode)
    ref = SyncVectorEnv([make] * 7, autoreset_mode=mode)
    assert ours.single_observation_space == ref.single_observation_space
    assert ours.action_space == ref.action_space
    run_both(ours, ref, steps=120, seed=4)
    ref.close()


def test_partial_resets_with_autoreset_disabled(hosted) -> None:
    mode = AutoresetMode.DISABLED
    ours = hosted(sync_of(InfoEnv, autoreset_mode=mode), 4, num_workers=2, autoreset_mode=mode)
    ref = SyncVectorEnv([InfoEnv] * 4, autoreset_mode=mode)
    run_both(ours, ref, steps=0, seed=2)
    done = np.zeros(4, bool)
    for _ in range(3):
        while not done.any():
            step = [v.step(np.zeros(4, np.int64)) for v in (ours, ref)]
            run_equal(*step)
            done = step[1][2] | step[1][3]
        with pytest.raises(ValueError, match="reset_mask"):
            ours.step(np.zeros(4, np.int64))
        run_equal(*(v.reset(options={"reset_mask": done}) for v in (ours, ref)))
        done[:] = False
    ref.close()


def run_equal(a: Any, b: Any) -> None:
    for x, y in zip(a, b):
        assert_tree_equal(x, y)


def test_env_exceptions_reach_the_caller_and_reset_recovers(hosted) -> None:
    env = hosted(sync_of(functools.partial(RaisingEnv, fail_after=1)), 4, num_workers=2)
    env.reset(seed=0)
    env.step(np.zeros(4, np.int64))
    with pytest.raises(SpecialError, match="step 2 refused action 1"):
        env.step(np.array([0, 0, 0, 1]))
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(4, np.int64))
    env.reset(seed=0)
    env.step(np.zeros(4, np.int64))


def test_bad_vector_env_functions_are_clear_errors() -> None:
    with pytest.raises(TypeError, match="not a gymnasium VectorEnv"):
        PoolVectorEnv.from_vector_env(lambda n: cartpole(), 2, num_workers=1)
    with pytest.raises(ValueError, match="built a vector env of 2 envs"):
        PoolVectorEnv.from_vector_env(lambda n: SyncVectorEnv([cartpole] * (n + 1)), 2)
    with pytest.raises(ValueError, match="autoresets SAME_STEP but the pool NEXT_STEP"):
        PoolVectorEnv.from_vector_env(sync_of(cartpole, autoreset_mode="SameStep"), 2)
    with pytest.raises(ValueError, match="autoresets NEXT_STEP but the pool SAME_STEP"):
        PoolVectorEnv.from_vector_env(sync_of(cartpole), 2, autoreset_mode="SameStep")
    with pytest.raises(ValueError, match="num_envs must be at least 1"):
        PoolVectorEnv.from_vector_env(sync_of(cartpole), 0)


def test_killed_worker_rebuilds_its_block(hosted, monkeypatch) -> None:
    monkeypatch.setattr(leases, "LEND_MIN_BYTES", 0)  # the kept batch is lent
    assert_killed_worker_restarts(hosted(sync_of(cartpole), 4, num_workers=2))


def test_calls_reach_each_env_through_the_vector_env(hosted) -> None:
    env = hosted(sync_of(NestedEnv), 3, num_workers=2)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    assert env.call("scaled_t", 10, offset=1) == (11, 11, 11)
    assert env.get_attr("t") == (1, 1, 1)
    with pytest.raises(SpecialError, match="negative factor"):
        env.call("scaled_t", -1)
    env.set_attr("t", [5, 6, 7])
    assert env.get_attr("t") == (5, 6, 7)
    env.set_attr("t", 4)
    assert env.call("scaled_t", 2) == (8, 8, 8)
    with pytest.raises(NotImplementedError, match=r"a hosted vector env does not serve .*setattr"):
        env.call_envs("setattr", "t", [((1,), {})] * 3)


def test_render_set_attr_and_seeded_partial_reset_match_the_vector_env(hosted) -> None:
    """What a vector env hosted per worker serves beyond stepping: ``render()``,
    ``set_attr`` and a seeded partial reset give what the vector env in one process gives."""
    ours = hosted(sync_of(NestedEnv), 4, num_workers=2)
    ref = SyncVectorEnv([NestedEnv] * 4)
    try:
        for env in (ours, ref):
            env.reset(seed=3)
            env.set_attr("t", [1, 2, 3, 4])
        assert_tree_equal(ours.render(), tuple(e.render() for e in ref.envs))
        mask = np.array([False, True, False, True])
        got = ours.reset(seed=[None, 11, None, 13], options={"reset_mask": mask})
        want = ref.reset(seed=[None, 11, None, 13], options={"reset_mask": mask})
        assert_tree_equal(got[0], want[0])
        got = ours.reset(seed=20, options={"reset_mask": mask})
        want = ref.reset(seed=20, options={"reset_mask": mask})
        assert_tree_equal(got[0], want[0])
        actions = ref.action_space.sample()
        assert_tree_equal(ours.step(actions)[0], ref.step(actions)[0])
    finally:
        ref.close()


def test_sb3_vec_env_hosting_vector_envs_plays_as_dummy_vec_env() -> None:
    """``rogue_gym.sb3.PoolVecEnv.from_vector_env`` (SAME_STEP vector envs): the observations,
    rewards, dones and infos (``terminal_observation``, ``TimeLimit.truncated``) of SB3's
    ``DummyVecEnv`` over the same envs."""
    pytest.importorskip("stable_baselines3")
    from rogue_gym.sb3 import PoolVecEnv
    from stable_baselines3.common.vec_env import DummyVecEnv

    ours = PoolVecEnv.from_vector_env(
        sync_of(cartpole, autoreset_mode=AutoresetMode.SAME_STEP), 5, num_workers=2
    )
    ref = DummyVecEnv([cartpole] * 5)
    try:
        ours.seed(3)
        ref.seed(3)
        assert np.array_equal(ours.reset(), ref.reset())
        rng = np.random.default_rng(0)
        ends = 0
        for _ in range(150):
            actions = rng.integers(0, 2, 5)
            (o1, r1, d1, i1), (o2, r2, d2, i2) = ours.step(actions), ref.step(actions)
            assert np.array_equal(o1, o2) and np.array_equal(r1, r2) and np.array_equal(d1, d2)
            for a, b in zip(i1, i2):
                episode = a.pop("episode", None)  # Monitor's info: the pool adds it at an end
                assert (episode is not None) == ("terminal_observation" in b)
                if episode is not None:  # CartPole pays 1 per step
                    assert episode["r"] == episode["l"] > 0
                assert sorted(a) == sorted(b), (a, b)
                for key in b:
                    assert np.array_equal(a[key], b[key]), key
            ends += int(d2.sum())
        assert ends >= 5, "the run crosses episode ends"
    finally:
        ours.close()
        ref.close()


def test_a_seed_list_seeds_each_env(hosted) -> None:
    """Seeds that are not consecutive within a block reach each env as a list."""
    ours = hosted(sync_of(cartpole), 5, num_workers=2)
    ref = SyncVectorEnv([cartpole] * 5)
    seeds = [11, 3, 42, 7, 19]
    run_equal(ours.reset(seed=seeds), ref.reset(seed=seeds))
    for _ in range(30):
        run_equal(ours.step(np.ones(5, np.int64)), ref.step(np.ones(5, np.int64)))
    ref.close()


def test_env_operations_run_once_per_env(hosted) -> None:
    """A vector env gets one call per worker block: call() runs the method once on each env
    (6 envs in blocks of 3 each bumped once, not 3 times), get_attr reads each env's own
    value, set_attr sets a new attribute; a call of some envs only is refused, clearly."""
    env = hosted(sync_of(CountingEnv), 6, num_workers=2)
    env.reset(seed=0)
    assert env.call("bump") == (1,) * 6
    assert env.get_attr("bumps") == (1,) * 6
    assert env.call("bump") == (2,) * 6
    env.set_attr("spam", [10, 11, 12, 13, 14, 15])
    assert env.get_attr("spam") == (10, 11, 12, 13, 14, 15)
    env.set_attr("spam", 7)
    assert env.get_attr("spam") == (7,) * 6
    with pytest.raises(ValueError, match="runs a call on all its 3 envs"):
        env.call_envs("call", "bump", [((), {})], indices=[4])
    assert env.get_attr("bumps") == (2,) * 6, "a refused call ran nowhere"


def test_env_operations_run_once_per_env_in_hosted_pools() -> None:
    """The same counts with one gymnasium env per row (the hosted kind)."""
    env = PoolVectorEnv([CountingEnv] * 4, num_workers=2)
    try:
        env.reset(seed=0)
        assert env.call("bump") == (1,) * 4
        assert env.call("bump") == (2,) * 4
        env.set_attr("spam", [1, 2, 3, 4])
        assert env.get_attr("spam") == (1, 2, 3, 4)
    finally:
        env.close()


def test_env_operations_run_once_per_env_of_the_native_game() -> None:
    """The third kind: the native game answers env operations in the caller, once per env."""
    import rogue_gym

    env = rogue_gym.make_vec(4, config="paper", num_workers=2, seed=0)
    try:
        kind = env._kind
        seen: list[int] = []
        real = kind._attribute
        kind._attribute = lambda name, e: (seen.append(e), real(name, e))[1]
        env.reset(seed=0)
        assert env.call("max_steps") == (500,) * 4
        assert sorted(seen) == [0, 1, 2, 3]
        seen.clear()
        assert len(env.get_attr("episode_seed")) == 4
        assert sorted(seen) == [0, 1, 2, 3]
    finally:
        env.close()
