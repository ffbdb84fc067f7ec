"""Any gymnasium env hosted in the pool (``PoolVectorEnv``): the same trajectories as
gymnasium's own vector envs, every supported space both ways, env exceptions, crashes, hangs,
seeding across worker layouts, and cleanup."""

from __future__ import annotations

import functools
import os
import re
import select
import signal
import subprocess
import sys
from collections.abc import Iterator
from typing import Any, Callable

import gymnasium as gym
import numpy as np
import pytest
import rogue_gym
from gymnasium.vector import AutoresetMode, SyncVectorEnv
from gymnasium.vector.utils import concatenate, create_empty_array
from rogue_gym import PoolVectorEnv, WorkerCrashedError
from rogue_gym.front import leases

from conftest import pid_alive, pool_files, wait_until
from hosted_envs import (
    BadStepEnv,
    BoundedEnv,
    FlatInfoEnv,
    GrowingInfoEnv,
    InfoEnv,
    NestedEnv,
    RaisingEnv,
    SpecialError,
    fails_in_workers,
)


def cartpole() -> gym.Env:
    return gym.make("CartPole-v1")


@pytest.fixture
def pool() -> Iterator[Callable[..., PoolVectorEnv]]:
    """``pool(env_fns, **kw)``: vector envs closed at teardown, checked for leftover files
    and workers."""
    yield from tracked(PoolVectorEnv)


def tracked(
    make: Callable[..., PoolVectorEnv],
) -> Iterator[Callable[..., PoolVectorEnv]]:
    """For a fixture to ``yield from``: ``make`` as a factory whose vector envs are closed at
    teardown and checked for leftover files and workers."""
    made: list[PoolVectorEnv] = []

    def factory(*args: Any, **kw: Any) -> PoolVectorEnv:
        env = make(*args, **kw)
        made.append(env)
        return env

    yield factory
    for env in made:
        pids, name = env.worker_pids, env.pool_name
        env.close()
        assert wait_until(lambda pids=pids: not any(pid_alive(p) for p in pids))
        assert pool_files(name) == []


def assert_tree_equal(a: Any, b: Any, *, same_dtype: bool = True) -> None:
    """``a`` and ``b`` are equal trees of arrays: same keys, shapes and values (NaN equal to
    NaN) and, with ``same_dtype``, the same dtypes."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and sorted(a) == sorted(b), (list(a), list(b))
        for k in a:
            assert_tree_equal(a[k], b[k], same_dtype=same_dtype)
    elif isinstance(a, tuple):
        assert isinstance(b, tuple) and len(a) == len(b)
        for x, y in zip(a, b):
            assert_tree_equal(x, y, same_dtype=same_dtype)
    elif isinstance(a, np.ndarray) and a.dtype == object:  # final_obs: one entry per env
        assert isinstance(b, np.ndarray) and b.dtype == object and a.shape == b.shape
        for x, y in zip(a, b):
            if x is None or y is None:
                assert x is None and y is None
            else:
                assert_tree_equal(x, y, same_dtype=same_dtype)
    else:
        x, y = np.asarray(a), np.asarray(b)
        assert x.shape == y.shape, (x.shape, y.shape)
        assert x.dtype == y.dtype or not same_dtype, (x.dtype, y.dtype)
        assert np.array_equal(x, y, equal_nan=x.dtype.kind in "fc"), (x, y)


def rows(tree: Any, order: np.ndarray) -> Any:
    """Every array of ``tree`` (dicts and tuples of arrays) taken at the rows ``order``."""
    if isinstance(tree, dict):
        return {k: rows(v, order) for k, v in tree.items()}
    if isinstance(tree, tuple):
        return tuple(rows(v, order) for v in tree)
    return tree[order]


def run_both(
    ours: gym.vector.VectorEnv, ref: gym.vector.VectorEnv, steps: int, seed: int = 0
) -> None:
    """Step both vector envs with the same random actions; every output must be equal."""
    o1, i1 = ours.reset(seed=seed)
    o2, i2 = ref.reset(seed=seed)
    assert_tree_equal(o1, o2)
    assert_tree_equal(i1, i2)
    ref.action_space.seed(seed)
    for _ in range(steps):
        actions = ref.action_space.sample()
        r1, r2 = ours.step(actions), ref.step(actions)
        for x, y in zip(r1, r2):
            assert_tree_equal(x, y)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_cartpole_matches_sync_vector_env(pool, mode) -> None:
    ours = pool([cartpole] * 6, num_workers=2, autoreset_mode=mode)
    ref = SyncVectorEnv([cartpole] * 6, autoreset_mode=mode)
    assert ours.single_observation_space == ref.single_observation_space
    assert ours.action_space == ref.action_space and ours.metadata["autoreset_mode"] == mode
    run_both(ours, ref, steps=300, seed=7)
    ref.close()


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_nested_spaces_and_infos_match_sync_vector_env(pool, mode) -> None:
    """Dict/Tuple nests of Box float64/float16/uint8, Discrete with a start, MultiDiscrete and
    MultiBinary, as observations and as actions; infos on every step and reset."""
    ours = pool([NestedEnv] * 4, num_workers=2, autoreset_mode=mode)
    ref = SyncVectorEnv([NestedEnv] * 4, autoreset_mode=mode)
    assert ours.observation_space == ref.observation_space
    assert ours.action_space == ref.action_space
    run_both(ours, ref, steps=40, seed=3)
    ref.close()


#: Batch slots of the pools that test lending beyond the default two.
LENDING_SLOTS = 4


def test_observations_are_lent_kept_intact_or_views(pool, monkeypatch) -> None:
    """copy=True (the default) lends the shared-memory slot the workers wrote instead of
    copying it: no later step writes a slot while any array from it (even a view of a view)
    lives; batches kept past the free slots are copied; a loop that drops its batches never
    copies; small batches are copied. copy=False returns double-buffered views."""
    small = pool([NestedEnv] * 3, num_workers=2)
    obs, _ = small.reset(seed=0)
    assert obs["pos"].flags.owndata, "a batch under LEND_MIN_BYTES is a plain copy"
    monkeypatch.setattr(leases, "LEND_MIN_BYTES", 0)
    env = pool([NestedEnv] * 3, num_workers=2, batch_slots=LENDING_SLOTS)
    obs, _ = env.reset(seed=0)
    acts = env.action_space.sample()
    for _ in range(2 * LENDING_SLOTS):
        assert not obs["pos"].flags.owndata, "a dropped batch's slot is lent again, not copied"
        obs, *_ = env.step(acts)
    kept, snapshots, lent = [], [], []
    for _ in range(2 * LENDING_SLOTS):
        obs, *_ = env.step(acts)
        kept.append(obs["pos"][1:])  # a view of a view keeps the slot lent
        snapshots.append(obs["pos"][1:].copy())
        lent.append(not obs["pos"].flags.owndata)
        del obs
    for a, b in zip(kept, snapshots):
        assert_tree_equal(a, b)
    assert len({s.tobytes() for s in snapshots}) == len(snapshots), "every batch differs"
    assert lent == [True] * (LENDING_SLOTS - 1) + [False] * (LENDING_SLOTS + 1), (
        "all slots but one are lent, the batches beyond are copies"
    )
    assert kept[0].flags.writeable, "a lent batch is the caller's to write"
    del kept
    obs, *_ = env.step(acts)
    assert not obs["pos"].flags.owndata, "released slots are lent again"

    # The default two slots: a loop that holds the previous batch while it steps gets every
    # other batch lent (the one free slot is the workers'); a loop that drops it first, all.
    two = pool([NestedEnv] * 3, num_workers=2)
    obs, _ = two.reset(seed=0)
    lent = []
    for _ in range(6):
        obs, *_ = two.step(acts)  # the previous obs lives during the call
        lent.append(not obs["pos"].flags.owndata)
    assert lent in ([True, False] * 3, [False, True] * 3), lent
    for _ in range(4):
        del obs
        obs, *_ = two.step(acts)
        assert not obs["pos"].flags.owndata
    # One slot: the batch's observations, columns and extra-info room, each 64-byte aligned.
    slot = sum(-(-a.nbytes // 64) * 64 for a in two._core.pool.slot_views()[0] if a is not None)
    assert env.stats().buffer_bytes - two.stats().buffer_bytes == (LENDING_SLOTS - 2) * slot

    views = pool([cartpole] * 2, num_workers=1, copy=False)
    obs, _ = views.reset(seed=0)
    assert not obs.flags.owndata
    nxt, *_ = views.step(np.ones(2, np.int64))
    assert not np.shares_memory(obs, nxt), "double buffered: the last batch stays intact"


def test_trajectories_do_not_depend_on_the_worker_layout(pool) -> None:
    """1, 2, 4 and 8 workers, and uneven blocks (3 and 5 workers for 8 envs)."""
    runs = []
    for workers in (1, 2, 3, 4, 5, 8):
        env = pool([NestedEnv] * 8, num_workers=workers)
        obs, _ = env.reset(seed=11)
        env.action_space.seed(5)
        trace = [obs["grid"].copy()]
        for _ in range(30):
            obs, rew, term, trunc, _ = env.step(env.action_space.sample())
            trace += [obs["grid"].copy(), rew, term]
        runs.append(trace)
        env.close()
    for other in runs[1:]:
        for x, y in zip(runs[0], other):
            assert np.array_equal(x, y)


def test_seeding_follows_gymnasium(pool) -> None:
    env = pool([NestedEnv] * 3, num_workers=1)
    a, _ = env.reset(seed=[5, 6, 7])
    b, _ = env.reset(seed=5)
    assert np.array_equal(a["grid"], b["grid"]), "seed=s seeds env i with s + i"
    c, _ = env.reset()  # no seed: every env continues its own generator
    assert not np.array_equal(b["grid"], c["grid"])
    single = NestedEnv()
    o, _ = single.reset(seed=6)
    assert np.array_equal(o["grid"], a["grid"][1])


def test_async_send_recv_plays_the_same_games_as_step(pool) -> None:
    """EnvPool-style async with half-size batches (one worker block each), dict actions."""
    n, steps = 4, 12
    space = NestedEnv.action_space

    def action(env: int, t: int) -> Any:
        space.seed(1000 * env + t)
        return space.sample()

    def batch(envs: list[int], ts: list[int]) -> Any:
        out = create_empty_array(space, len(envs))
        return concatenate(space, [action(e, t) for e, t in zip(envs, ts)], out)

    sync = pool([NestedEnv] * n, num_workers=2)
    obs, _ = sync.reset(seed=3)
    want: list[list[Any]] = [[obs["grid"][i].copy()] for i in range(n)]
    for t in range(steps):
        obs, rew, *_ = sync.step(batch(list(range(n)), [t] * n))
        for i in range(n):
            want[i] += [obs["grid"][i].copy(), rew[i]]

    env = pool([NestedEnv] * n, num_workers=2, batch_size=2)
    env.async_reset(seed=3)
    got: list[list[Any]] = [[] for _ in range(n)]
    done = [0] * n  # results received per env
    while min(done) < steps + 1:
        obs, rew, _, _, infos = env.recv()
        ids = infos["env_id"].tolist()
        assert len(ids) == 2, "one worker block per batch"
        assert "t" in infos or "start" in infos, "the envs' infos come along"
        for r, e in enumerate(ids):
            if done[e] < steps + 1:
                got[e] += [obs["grid"][r].copy()] + ([rew[r]] if done[e] else [])
            done[e] += 1
        env.send(batch(ids, [done[e] - 1 for e in ids]))
    for i in range(n):
        assert len(got[i]) == len(want[i])
        for x, y in zip(got[i], want[i]):
            assert np.array_equal(x, y)


def test_call_get_attr_set_attr_render_and_reset_options(pool) -> None:
    env = pool([NestedEnv] * 3, num_workers=2)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    assert env.call("scaled_t", 10, offset=1) == (11, 11, 11)
    assert env.get_attr("t") == (1, 1, 1)
    env.set_attr("t", [5, 6, 7])
    assert env.get_attr("t") == (5, 6, 7)
    env.set_attr("t", 2)
    frames = env.render()
    assert len(frames) == 3 and all((f == 2).all() and f.shape == (2, 2, 3) for f in frames)
    with pytest.raises(SpecialError, match="negative factor"):
        env.call("scaled_t", -1)
    env.reset(options={"level": 3})
    assert env.get_attr("options") == ({"level": 3},) * 3
    env.reset()
    assert env.get_attr("options") == (None,) * 3, "options apply to one reset"


def test_env_exceptions_reach_the_caller_and_reset_recovers(pool) -> None:
    env = pool([functools.partial(RaisingEnv, fail_after=1)] * 4, num_workers=2)
    env.reset(seed=0)
    env.step(np.zeros(4, np.int64))
    with pytest.raises(SpecialError, match="step 2 refused action 1") as info:
        env.step(np.array([0, 0, 0, 1]))
    notes = "\n".join(getattr(info.value, "__notes__", []))
    if notes:  # Python 3.11+: the worker-side traceback travels as a note
        assert "raised by env 3 during step" in notes and "hosted_envs.py" in notes
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(4, np.int64))
    obs, _ = env.reset(seed=0)  # usable again
    env.step(np.zeros(4, np.int64))

    with pytest.raises(SpecialError, match="seed 999"):
        env.reset(seed=996)  # env 3 gets seed 999
    env.reset(seed=0)
    env.step(np.zeros(4, np.int64))


def test_a_step_that_breaks_the_api_says_how_and_reset_recovers(pool) -> None:
    """A step's output that is not gymnasium's (four values, a reward that is not a number)
    is an error naming the problem, raised here; the pool works again after reset()."""
    env = pool([BadStepEnv] * 2, num_workers=2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="returned 4 values; expected 5"):
        env.step(np.array([1, 0]))
    env.reset(seed=0)
    with pytest.raises(TypeError, match="reward of type str; expected a number"):
        env.step(np.array([0, 1]))
    env.reset(seed=0)
    obs, rewards, *_ = env.step(np.array([0, 0]))
    assert rewards.tolist() == [1.0, 1.0]


def test_constructor_exceptions_reach_the_caller() -> None:
    with pytest.raises(SpecialError, match="no env in a worker"):
        PoolVectorEnv([functools.partial(fails_in_workers, os.getpid())] * 2, num_workers=1)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_numeric_infos_match_sync_vector_env_bit_for_bit(pool, mode) -> None:
    """Per-step infos of numbers and arrays (typed rows in shared memory), mixed with values
    that only pickle: the same keys, dtypes, masks, nesting and values as SyncVectorEnv's,
    through step() and through recv()."""
    ours = pool([InfoEnv] * 6, num_workers=2, autoreset_mode=mode)
    ref = SyncVectorEnv([InfoEnv] * 6, autoreset_mode=mode)
    run_both(ours, ref, steps=80, seed=5)
    ref.close()
    if mode == AutoresetMode.NEXT_STEP:
        ref = SyncVectorEnv([InfoEnv] * 6)
        ref.reset(seed=9)
        ours.async_reset(seed=9)
        ours.recv()
        actions = np.zeros(6, np.int64)
        ours.send(actions, np.arange(6))
        for t in range(40):
            obs, rew, term, trunc, infos = ours.recv()
            ids = infos.pop("env_id")
            assert sorted(ids.tolist()) == list(range(6))
            by_env = rows((obs, rew, term, trunc, infos), np.argsort(ids))
            # The rows come in arrival order, and the first row of a key sets its dtype (here
            # "count", an int at reset and a float on steps): values are compared.
            assert_tree_equal(by_env, ref.step(actions), same_dtype=False)
            actions = np.full(6, t % 2, np.int64)
            ours.send(actions, ids)
        ref.close()


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_flat_infos_packed_by_the_workers_match_sync_vector_env(pool, mode) -> None:
    """Flat infos of every scalar kind, which the workers pack without Python while their keys
    and types repeat (and hand back to the adapter when they change), observations that are
    views, numpy rewards and flags: all equal to SyncVectorEnv's."""
    ours = pool([FlatInfoEnv] * 6, num_workers=2, autoreset_mode=mode)
    ref = SyncVectorEnv([FlatInfoEnv] * 6, autoreset_mode=mode)
    run_both(ours, ref, steps=90, seed=11)
    ref.close()


def test_infos_larger_than_the_room_travel_beside_the_block(pool) -> None:
    """Infos that outgrow the default room (4096 bytes per env), typed and pickled, some envs
    of a block in it and others beside it: never an error, equal to SyncVectorEnv's."""
    ours = pool([GrowingInfoEnv] * 4, num_workers=2)
    ref = SyncVectorEnv([GrowingInfoEnv] * 4)
    run_both(ours, ref, steps=60, seed=1)
    ref.close()
    aux = os.path.join(rogue_gym._native.default_runtime_dir(), f"{ours.pool_name}.d")
    assert not [f for f in os.listdir(aux) if "extra" in f], "side files are removed as read"


def test_bad_actions_are_clear_errors(pool) -> None:
    env = pool([NestedEnv] * 2, num_workers=1)
    env.reset(seed=0)
    actions = env.action_space.sample()
    actions["pick"] = np.array([1, 7])
    with pytest.raises(ValueError, match=r"env 1: action\['pick'\] 7"):
        env.step(actions)
    actions = env.action_space.sample()
    actions["move"] = np.zeros((3, 2))
    with pytest.raises(ValueError, match=r"\['move'\] has shape \(3, 2\)"):
        env.step(actions)
    cp = pool([cartpole] * 2, num_workers=1)
    cp.reset(seed=0)
    with pytest.raises(ValueError, match="out of range"):
        cp.step(np.array([0, 2]))


def test_killed_worker_is_restarted_with_flagged_envs(pool, monkeypatch) -> None:
    monkeypatch.setattr(leases, "LEND_MIN_BYTES", 0)  # the kept batch is lent
    assert_killed_worker_restarts(pool([cartpole] * 4, num_workers=2))


def assert_killed_worker_restarts(env: PoolVectorEnv) -> None:
    """Kill worker 1 of a pool of 4 CartPole-like envs in 2 workers: its envs' episodes end
    (truncated, ``worker_restarted``), a new worker takes over and the pool steps on; the
    observations the caller kept from before stay as they were."""
    first, _ = env.reset(seed=0)
    kept = first.copy()
    victim = env.worker_pids[1]
    os.kill(victim, signal.SIGKILL)
    _, _, _, trunc, infos = env.step(np.zeros(4, np.int64))
    assert infos["worker_restarted"].tolist() == [False, False, True, True]
    assert trunc[2:].all()
    assert env.worker_pids[1] != victim
    for _ in range(2 * LENDING_SLOTS):
        env.step(np.zeros(4, np.int64))
    assert np.array_equal(first, kept), "a restart never writes a batch the caller holds"


def test_hung_worker_is_restarted(pool) -> None:
    env = pool([cartpole] * 2, num_workers=2, step_timeout=1.0)
    env.reset(seed=0)
    victim = env.worker_pids[0]
    os.kill(victim, signal.SIGSTOP)
    try:
        _, _, _, trunc, infos = env.step(np.zeros(2, np.int64))
    finally:
        if pid_alive(victim):
            os.kill(victim, signal.SIGKILL)
    assert infos["worker_restarted"].tolist() == [True, False] and trunc[0]


def test_killed_worker_raises_under_raise_policy(pool) -> None:
    env = pool([cartpole] * 2, num_workers=2, on_worker_failure="raise")
    env.reset(seed=0)
    victim = env.worker_pids[1]
    os.kill(victim, signal.SIGKILL)
    with pytest.raises(WorkerCrashedError) as info:
        env.step(np.zeros(2, np.int64))
    assert info.value.pid == victim and info.value.signal == signal.SIGKILL
    assert info.value.envs == (1,)
    env.reset(seed=0)
    env.step(np.zeros(2, np.int64))


def test_make_vec_builds_any_registered_id(pool) -> None:
    env = rogue_gym.make_vec("CartPole-v1", 4, num_workers=2, env_kwargs={"max_episode_steps": 5})
    try:
        env.reset(seed=0)
        for _ in range(5):
            _, _, _, trunc, _ = env.step(np.zeros(4, np.int64))
        assert trunc.all(), "env_kwargs reach gymnasium.make"
    finally:
        env.close()
    with pytest.raises(TypeError, match="num_envs"):
        rogue_gym.make_vec("CartPole-v1")


SIGTERM_SCRIPT = """
import gymnasium as gym, numpy as np, rogue_gym
envs = rogue_gym.PoolVectorEnv([lambda: gym.make("CartPole-v1")] * 4, num_workers=2)
envs.reset(seed=0)
print(envs.pool_name, *envs.worker_pids, flush=True)
while True:
    envs.step(np.zeros(4, np.int64))
"""


def test_sigterm_stops_the_workers_and_removes_every_file() -> None:
    proc = subprocess.Popen(
        [sys.executable, "-c", SIGTERM_SCRIPT], stdout=subprocess.PIPE, text=True
    )
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 120)
        assert ready, "the child did not start its pool within 120 s"
        assert proc.stdout is not None
        name, *pids = proc.stdout.readline().split()
        assert pool_files(name)
        os.kill(proc.pid, signal.SIGTERM)
        assert proc.wait(timeout=60) == 128 + signal.SIGTERM
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert wait_until(lambda: not any(pid_alive(int(p)) for p in pids))
    assert pool_files(name) == []


def test_several_envs_raising_in_one_step_are_all_reported_and_one_reset_recovers(pool) -> None:
    env = pool([functools.partial(RaisingEnv, fail_after=1)] * 4, num_workers=2)
    env.reset(seed=0)
    env.step(np.zeros(4, np.int64))
    # Env 1 (worker 0) and env 3 (worker 1) raise in the same step.
    with pytest.raises(SpecialError, match="step 2 refused action 1") as info:
        env.step(np.array([0, 1, 0, 1]))
    others = info.value.others  # type: ignore[attr-defined]
    assert len(others) == 1 and isinstance(others[0], SpecialError), others
    for e in [info.value, *others]:
        assert "rogue_gym_exception" not in str(e), "no raw JSON in a message"
    env.reset(seed=0)  # one reset clears both
    env.step(np.zeros(4, np.int64))


def test_bad_arguments_name_the_argument_and_its_range(make_vec) -> None:
    with pytest.raises(ValueError, match=r"seed must be an integer in \[0, 2\*\*64\), got -1"):
        make_vec(seed=-1)
    with pytest.raises(ValueError, match=r"seed must be an integer in \[0, 2\*\*64\)"):
        make_vec(seed=2**70)
    with pytest.raises(
        ValueError, match=r"num_workers must be between 1 and num_envs \(4\), got 0"
    ):
        make_vec(num_workers=0)
    with pytest.raises(ValueError, match="num_workers must be between 1"):
        PoolVectorEnv([cartpole] * 2, num_workers=0)
    with pytest.raises(TypeError, match=r"returned 'int', not a gymnasium\.Env"):
        PoolVectorEnv([lambda: 3] * 2, num_workers=1)
    envs = make_vec()
    envs.reset()
    with pytest.raises(
        ValueError,
        match=r"action 18446744073709551615 is out of range; valid actions are 0 to 10 \(range\(11\)\)",
    ):
        envs.step(np.array([0, 0, 0, 2**64 - 1], np.uint64))


class _CheckedActionEnv(gym.Env):
    """Asserts that every action it gets is in its action space."""

    observation_space = gym.spaces.Box(0.0, 1.0, (1,), np.float32)

    def __init__(self, space: gym.Space) -> None:
        self.action_space = space

    def reset(self, *, seed: Any = None, options: Any = None) -> Any:
        super().reset(seed=seed)
        return np.zeros(1, np.float32), {}

    def step(self, action: Any) -> Any:
        assert action in self.action_space, (action, self.action_space)
        return np.zeros(1, np.float32), 0.0, False, False, {}


ACTION_SPACES = [
    gym.spaces.Discrete(4),
    gym.spaces.Discrete(4, start=1, dtype=np.int32),
    gym.spaces.Discrete(3, start=-1, dtype=np.int8),
    gym.spaces.Box(-1.0, 1.0, (2,), np.float32),
    gym.spaces.Box(-1.0, 1.0, (2, 3), np.float64),
    gym.spaces.Box(0, 255, (3,), np.uint8),
    gym.spaces.Box(-5, 5, (2,), np.int64),
    gym.spaces.MultiDiscrete([2, 3, 4]),
    gym.spaces.MultiDiscrete([2, 3], start=[-1, 1], dtype=np.int32),
    gym.spaces.MultiBinary(5),
    gym.spaces.MultiBinary([2, 2]),
    gym.spaces.Dict({"pick": gym.spaces.Discrete(3, start=2), "move": gym.spaces.Box(-1, 1, (2,))}),
    gym.spaces.Tuple((gym.spaces.Discrete(2), gym.spaces.MultiBinary(3))),
]


@pytest.mark.parametrize("space", ACTION_SPACES, ids=str)
def test_every_action_space_reaches_the_env_inside_its_space(pool, space) -> None:
    env = pool([functools.partial(_CheckedActionEnv, space)] * 2, num_workers=1)
    env.reset(seed=0)
    env.action_space.seed(0)
    for _ in range(5):
        env.step(env.action_space.sample())  # the env raises if an action is outside its space


def test_discrete_actions_outside_the_space_are_named_in_the_callers_terms(pool) -> None:
    space = gym.spaces.Discrete(3, start=-1, dtype=np.int8)
    env = pool([functools.partial(_CheckedActionEnv, space)] * 2, num_workers=1)
    env.reset(seed=0)
    with pytest.raises(
        ValueError, match=r"env 1: action 2 is out of range of .*valid actions are -1 to 1"
    ):
        env.step(np.array([0, 2]))
    env.step(np.array([-1, 1]))


class _EchoActionEnv(gym.Env):
    """Observes the MultiDiscrete action it was given."""

    observation_space = gym.spaces.Box(0.0, 10.0, (3,), np.float32)
    action_space = gym.spaces.MultiDiscrete([2, 3, 4])

    def reset(self, *, seed: Any = None, options: Any = None) -> Any:
        super().reset(seed=seed)
        return np.zeros(3, np.float32), {}

    def step(self, action: Any) -> Any:
        return np.asarray(action, np.float32), 0.0, False, False, {}


def test_action_batches_of_any_layout_arrive_and_are_checked(pool) -> None:
    """An action batch is sent as it is when it is a C-contiguous array of the space's dtype,
    and converted otherwise (another dtype, Fortran order, a strided view, a list); either
    way each env gets its row, and a row outside the space is refused, naming its env."""
    env = pool([_EchoActionEnv] * 2, num_workers=2)
    env.reset(seed=0)
    good = np.array([[1, 2, 3], [0, 1, 2]], np.int64)
    wide = np.zeros((2, 6), np.int64)
    wide[:, ::2] = good
    for batch in (
        good,
        good.astype(np.int32),
        np.asfortranarray(good),
        wide[:, ::2],
        good.tolist(),
    ):
        obs, *_ = env.step(batch)
        np.testing.assert_array_equal(obs, good.astype(np.float32))
    with pytest.raises(ValueError, match=r"env 1: action \[0, 3, 0\] is outside"):
        env.step(np.array([[1, 2, 3], [0, 3, 0]], np.int64))
    obs, *_ = env.step(good[::-1].copy())
    np.testing.assert_array_equal(obs, good[::-1].astype(np.float32))


def test_actions_decode_to_fresh_writable_values_of_their_space() -> None:
    """What a worker hands an env for an action's bytes: the same value, as a writable array
    of its own (the env may keep or change it), for one-array and nested spaces."""
    from gymnasium import spaces
    from rogue_gym.protocol.layout import SpaceLayout

    for space in (
        spaces.Box(-1, 1, (6,), np.float32),
        spaces.Box(0, 9, (2, 3), np.int16),
        spaces.Box(-1, 1, (), np.float64),
        spaces.Dict({"a": spaces.Discrete(3), "b": spaces.Box(0, 1, (2,))}),
    ):
        layout = SpaceLayout(space)
        decode = layout.decoder()
        space.seed(1)
        value = space.sample()
        data = bytearray(layout.nbytes)
        layout.writer(np.frombuffer(data, np.uint8).ctypes.data)(value)
        first, second = decode(bytes(data)), decode(bytes(data))
        assert_tree_equal(first, value)
        for leaf in first.values() if isinstance(first, dict) else [first]:
            if isinstance(leaf, np.ndarray):
                assert leaf.flags.writeable
        if isinstance(first, np.ndarray) and first.ndim:
            first[...] = 0  # each decode is a fresh array: the second is untouched
            assert_tree_equal(second, value)


def test_info_rows_are_typed_when_they_can_be() -> None:
    """Numbers and arrays in nested dicts travel as typed rows, read back as the same values
    of the same types; anything else is pickled; many rows become columns at once."""
    from rogue_gym.protocol.infos import (
        MAGIC,
        InfoDecoder,
        InfoEncoder,
        add_row_info,
        split_joined,
    )

    enc, dec = InfoEncoder(), InfoDecoder()
    info = {
        "i": 3,
        "f": 0.25,
        "b": True,
        "f32": np.float32(1.5),
        "u8": np.uint8(7),
        "a": np.arange(6, dtype=np.int16).reshape(2, 3),
        "d": {"x": -1, "e": {}},
    }
    data = enc.encode([("step", info)])
    assert data.startswith(MAGIC)
    [(kind, back)] = dec.entries(data)
    assert kind == "step"
    assert {k: type(v) for k, v in back.items()} == {k: type(v) for k, v in info.items()}
    assert_tree_equal(back, info)
    # The same keys with other value types, one after the other, are other layouts.
    for value in (1.5, np.float32(1.5), True, 2, 2**70, np.int16(3), 2.5):
        [(_, again)] = dec.entries(enc.encode([("step", {"v": value})]))
        assert type(again["v"]) is type(value) and again["v"] == value, value
    for untyped in ({"s": "text"}, {"nb": np.bool_(True)}, {"big": 2**70}, {"l": [1]}):
        assert not enc.encode([("step", untyped)]).startswith(MAGIC), untyped
    assert not enc.encode([("step", info), ("reset", info)]).startswith(MAGIC)

    # Some rows, every row, and rows of two kinds and two structures (grouped, the lowest
    # row's group first): the columns are what gymnasium builds one row at a time.
    other = {"f": np.float32(2.0), "extra": np.ones(3)}
    for kinds in (
        {0: ("step", info), 2: ("step", info), 3: ("step", info)},
        {r: ("step", info) for r in range(5)},
        {0: ("step", other), 1: ("reset", info), 2: ("step", info), 4: ("reset", other)},
    ):
        rows = [(r, enc.encode([(k, {**i, "i": r})])) for r, (k, i) in kinds.items()]
        columns: dict = {}
        assert dec.put_typed(columns, rows, 5)
        one_by_one: dict = {}
        for r, (_, i) in kinds.items():
            one_by_one = add_row_info(one_by_one, {**i, "i": r}, r, 5)
        assert list(columns) == list(one_by_one), "gymnasium's key order"
        assert_tree_equal(columns, one_by_one)
        assert all(a.flags.c_contiguous for a in columns.values() if isinstance(a, np.ndarray))
    pickled = [(0, rows[0][1]), (1, enc.encode([("step", {"s": "text"})]))]
    assert not dec.put_typed({}, pickled, 2), "a pickled row is not typed"
    # The pool's joined extras, split again: rows of one size, or of any sizes (their ends).
    assert split_joined(None, b"aabbcc", 2, [], 3) == [(0, b"aa"), (1, b"bb"), (2, b"cc")]
    assert split_joined([1, 4], b"abbb", 0, [1, 4], 5) == [(1, b"a"), (4, b"bbb")]


def test_an_unknown_observation_mode_gets_gymnasiums_message() -> None:
    message = "Invalid `observation_mode`, expected: 'same' or 'different'"
    with pytest.raises(ValueError, match=re.escape(message)):
        PoolVectorEnv([lambda: gym.make("CartPole-v1")] * 2, observation_mode="invalid")


def test_per_env_observation_spaces_as_gymnasium_takes_them(pool) -> None:
    """``observation_mode="different"`` and a ``(batch, single)`` pair batch spaces that differ
    in their bounds; with ``"same"``, such envs are gymnasium's RuntimeError naming the mode."""
    from gymnasium.vector.utils import batch_differing_spaces

    fns = [functools.partial(BoundedEnv, float(i + 1)) for i in range(3)]
    per_env = [fn().observation_space for fn in fns]
    envs = pool(fns, num_workers=2, observation_mode="different")
    assert envs.observation_space == batch_differing_spaces(per_env)
    assert envs.single_observation_space == per_env[0]
    obs, _ = envs.reset(seed=0)
    assert obs.shape == (3, 4) and obs in envs.observation_space
    pair = (batch_differing_spaces(per_env), per_env[0])
    envs = pool(fns, num_workers=2, observation_mode=pair)
    assert envs.observation_space == pair[0]
    envs.reset(seed=0)
    assert envs.step(envs.action_space.sample())[0] in envs.observation_space
    with pytest.raises(RuntimeError, match="observation_mode='different'"):
        PoolVectorEnv(fns, num_workers=1)


def test_partial_reset_with_seeds_seeds_only_the_masked_envs(pool) -> None:
    """``reset(seed=..., options={"reset_mask": m})``: the masked envs start again from their
    seeds, the others go on; ``np_random_seed`` is each env's, as AsyncVectorEnv's."""
    envs = pool([cartpole] * 3, num_workers=2, autoreset_mode=AutoresetMode.DISABLED)
    first, _ = envs.reset(seed=[0, 1, 2])
    assert envs.np_random_seed == (0, 1, 2)
    for _ in range(3):
        stepped, *_ = envs.step(np.zeros(3, np.int64))
    again, _ = envs.reset(seed=[0, 5, 9], options={"reset_mask": np.array([True, False, False])})
    np.testing.assert_array_equal(again[0], first[0])
    np.testing.assert_array_equal(again[1:], stepped[1:])
    assert envs.np_random_seed == (0, 1, 2)
    again, _ = envs.reset(seed=10, options={"reset_mask": np.array([False, True, True])})
    assert envs.np_random_seed == (0, 11, 12)
