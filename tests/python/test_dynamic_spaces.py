"""Spaces of no fixed size (Text, Graph, Sequence, OneOf, custom) hosted in the pool: their
values travel pickled per env while the fixed-size leaves beside them stay in shared memory,
for observations and actions, in every autoreset mode and call; MiniGrid runs unwrapped. The
spaces one by one, both ways, are gymnasium's own tests (test_gymnasium_conformance.py)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, Callable

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv
from rogue_gym import PoolVectorEnv
from rogue_gym.protocol import UnsupportedSpaceError

from hosted_envs import NestedEnv, NoteEnv, TextEnv, WordEnv
from test_hosted import assert_tree_equal, run_both, tracked


@pytest.fixture
def pool() -> Iterator[Callable[..., PoolVectorEnv]]:
    """``pool(env_fns, **kw)``: closed at teardown, checked for leftover files and workers."""
    yield from tracked(PoolVectorEnv)


@pytest.mark.parametrize(
    "mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP], ids=["next", "same"]
)
def test_dynamic_leaves_match_sync_vector_env(pool, mode) -> None:
    """Text and Sequence leaves beside a Box, and a Text action leaf, over several episodes:
    observations (final ones too), rewards and infos equal SyncVectorEnv's; the Text grows past
    the room per env in shared memory (4096 bytes) and goes on beside it."""
    ours = pool([NoteEnv] * 4, num_workers=2, autoreset_mode=mode)
    ref = SyncVectorEnv([NoteEnv] * 4, autoreset_mode=mode)
    assert ours.observation_space == ref.observation_space
    assert ours.action_space == ref.action_space
    run_both(ours, ref, steps=20, seed=5)
    ref.close()
    assert ours.stats().info_rows_pickled > 0


def test_fixed_leaves_stay_zero_copy_and_nothing_is_pickled_without_dynamic_leaves(pool) -> None:
    ours = pool([NoteEnv] * 2, num_workers=1, copy=False)
    obs, _ = ours.reset(seed=0)
    slot = ours._core.slots[ours._core.state.slot]
    assert np.shares_memory(obs["pos"], slot), "the Box leaf is a view of shared memory"
    assert isinstance(obs["note"], tuple) and obs["note"] == ("", "")
    fixed = pool([NestedEnv] * 2, num_workers=1)
    fixed.reset(seed=0)
    for _ in range(5):
        fixed.step(fixed.action_space.sample())
    assert fixed.stats().info_rows_pickled == 0


def test_partial_reset_keeps_the_other_envs_dynamic_values(pool) -> None:
    ours = pool([NoteEnv] * 3, num_workers=2, autoreset_mode=AutoresetMode.DISABLED)
    ours.reset(seed=1)
    act = {"move": np.zeros(3, np.int64), "say": ("ab", "cd", "ef")}
    obs, *_ = ours.step(act)
    assert obs["note"] == tuple(s + "x" * 1000 for s in ("ab", "cd", "ef"))
    mask = np.array([False, True, False])
    again, _ = ours.reset(options={"reset_mask": mask})
    assert again["note"] == (obs["note"][0], "", obs["note"][2])
    assert again["path"][0] == obs["path"][0] and again["path"][2] == obs["path"][2]


def test_async_send_and_recv_carry_dynamic_values_both_ways(pool) -> None:
    """EnvPool-style send/recv of some workers at a time: each env's Text action reaches it
    with its own step (the others are busy meanwhile), and its Text observation comes back."""
    ours = pool([NoteEnv] * 4, num_workers=2, batch_size=2)
    ours.async_reset(seed=0)
    said: dict[int, str] = {}
    for t in range(6):
        obs, reward, _, _, infos = ours.recv()
        ids = [int(e) for e in infos["env_id"]]
        assert len(obs["note"]) == 2 and obs["pos"].shape == (2, 2)
        for row, env in enumerate(ids):
            if env in said:  # its last action's text, echoed (a step of its first episode)
                assert obs["note"][row].startswith(said[env]), (env, obs["note"][row])
                assert reward[row] == len(said[env])
        words = tuple(f"e{env}t{t}" for env in ids)
        said.update(zip(ids, words))
        ours.send({"move": np.zeros(2, np.int64), "say": words}, infos["env_id"])


def test_text_only_spaces_both_ways(pool) -> None:
    """A space that is one dynamic leaf, as observation and as action (no fixed bytes at all);
    step_async carries the actions too."""
    ours = pool([TextEnv] * 3, num_workers=2)
    obs, _ = ours.reset(seed=0)
    assert obs == ("start",) * 3 and obs in ours.observation_space
    obs, *_ = ours.step(("a", "bb", "ccc"))
    assert obs == ("a", "bb", "ccc")
    ours.step_async(("x", "y", "z"))
    obs, *_ = ours.step_wait(timeout=30)
    assert obs == ("x", "y", "z")
    with pytest.raises(ValueError, match="expected 3"):
        ours.step(("a", "b"))
    notes = pool([NoteEnv] * 3, num_workers=1)
    notes.reset(seed=0)
    with pytest.raises(TypeError, match=r"\['say'\] must be a tuple"):
        notes.step({"move": np.zeros(3, np.int64), "say": "abc"})


def test_shared_memory_true_and_vector_envs_refuse_dynamic_leaves_as_gymnasium_does(
    pool,
) -> None:
    """``shared_memory=True`` refuses what AsyncVectorEnv's shared memory cannot hold with its
    errors (a TypeError for a Sequence, a ValueError for a custom space) and takes Text, as it
    does; without it, a custom space is carried."""
    with pytest.raises(TypeError, match="dynamic shape"):
        PoolVectorEnv([NoteEnv] * 2, num_workers=1, shared_memory=True)
    text = pool([TextEnv] * 2, num_workers=1, shared_memory=True)
    assert text.reset(seed=0)[0] == ("start", "start")

    with pytest.raises(ValueError, match="custom space") as refused:
        PoolVectorEnv([WordEnv] * 2, num_workers=1, shared_memory=True)
    assert isinstance(refused.value.__cause__, gym.error.CustomSpaceError)
    words = pool([WordEnv] * 2, num_workers=1)
    assert words.reset(seed=0)[0] == ("reset", "reset")
    assert words.step(np.zeros(2, np.int64))[0] == ("step 1", "step 1")

    def text_vector(n: int) -> gym.vector.VectorEnv:
        return SyncVectorEnv([TextEnv] * n)

    with pytest.raises(UnsupportedSpaceError, match="fixed-size"):
        PoolVectorEnv.from_vector_env(text_vector, 2, num_workers=1)


def test_minigrid_runs_unwrapped_and_matches_sync_vector_env(pool) -> None:
    """MiniGrid's observation has a dynamic ``mission`` (a MissionSpace): its observations and
    rewards equal SyncVectorEnv's for the same seeds and actions, across the truncation at
    100 steps."""
    pytest.importorskip("minigrid")
    import minigrid  # noqa: F401  (registers the envs)

    def make() -> Any:
        return gym.make("MiniGrid-Empty-5x5-v0")

    ended = 0
    for mode in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
        ours = pool([make] * 4, num_workers=2, autoreset_mode=mode)
        ref = SyncVectorEnv([make] * 4, autoreset_mode=mode)
        assert ours.observation_space == ref.observation_space
        o1, _ = ours.reset(seed=3)
        o2, _ = ref.reset(seed=3)
        assert_tree_equal(o1, o2)
        assert isinstance(o1["mission"], tuple) and isinstance(o1["mission"][0], str)
        rng = np.random.default_rng(0)
        for _ in range(120):
            actions = rng.integers(0, 7, 4)
            got = ours.step(actions)
            for x, y in zip(got, ref.step(actions)):
                assert_tree_equal(x, y)
            ended += int(np.sum(got[3]))
        ref.close()
    assert ended >= 8, "every env's episode was cut at 100 steps, in each mode"
