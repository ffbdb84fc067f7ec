"""The pool as a gymnasium VectorEnv: semantics, determinism, crashes, cleanup, zero-copy."""

from __future__ import annotations

import os
import re
import signal

import gymnasium as gym
import numpy as np
import pytest
import rogue_gym
from gymnasium.error import ClosedEnvironmentError
from gymnasium.vector import AutoresetMode
from gymnasium.wrappers.vector import DictInfoToList, RecordEpisodeStatistics
from rogue_gym import WorkerCrashedError
from rogue_gym.envs import RogueEnv

from conftest import PAPER

INFO_KEYS = {
    "seed",
    "episode_index",
    "episode_return",
    "episode_length",
    "floor",
    "max_floor",
    "gold",
    "hp",
    "died",
    "won",
}


def _actions(n: int, steps: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 11, size=(steps, n))


def test_spaces_reset_step(make_vec) -> None:
    env = make_vec(4, max_steps=50)
    assert isinstance(env, gym.vector.VectorEnv)
    assert env.single_observation_space.shape == (17, 16, 32)
    assert env.observation_space.shape == (4, 17, 16, 32)
    assert env.single_action_space == gym.spaces.Discrete(11)
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    obs, infos = env.reset(seed=1)
    assert obs.dtype == np.uint8 and obs in env.observation_space
    assert set(infos) >= INFO_KEYS and all(infos[f"_{k}"].all() for k in INFO_KEYS)
    obs, rew, term, trunc, infos = env.step(env.action_space.sample())
    assert rew.dtype == np.float64 and rew.shape == (4,)
    assert term.dtype == np.bool_ and trunc.dtype == np.bool_
    assert obs in env.observation_space
    assert (infos["episode_length"] == 1).all()


def test_next_step_autoreset(make_vec) -> None:
    env = make_vec(4, max_steps=5)
    env.reset(seed=3)
    for _ in range(4):
        *_, trunc, infos = env.step(np.zeros(4, np.int64))
        assert not trunc.any()
    obs, rew, term, trunc, infos = env.step(np.zeros(4, np.int64))
    assert trunc.all() and not term.any()
    first_seeds = infos["seed"].copy()
    obs, rew, term, trunc, infos = env.step(np.full(4, 4, np.int64))  # actions ignored: reset step
    assert (rew == 0).all() and not term.any() and not trunc.any()
    assert (infos["episode_length"] == 0).all() and (infos["episode_index"] == 1).all()
    assert not np.array_equal(first_seeds, infos["seed"])


def test_same_step_autoreset_final_obs(make_vec) -> None:
    env = make_vec(4, max_steps=3, autoreset_mode="same_step")
    assert env.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    obs0, _ = env.reset(seed=0)
    last = None
    for _ in range(3):
        last = obs0.copy()
        obs0, rew, term, trunc, infos = env.step(np.zeros(4, np.int64))
    assert trunc.all()
    assert infos["_final_obs"].all() and infos["final_info"]["episode_length"].tolist() == [3] * 4
    # No-op steps: the final observation equals the one before it; the returned one is new.
    assert all(np.array_equal(infos["final_obs"][i], last[i]) for i in range(4))


def test_record_episode_statistics_wrapper(make_vec) -> None:
    env = RecordEpisodeStatistics(make_vec(4, max_steps=10))
    env.reset(seed=0)
    episodes = 0
    for a in _actions(4, 25):
        *_, infos = env.step(a)
        if "episode" in infos:
            episodes += int(infos["_episode"].sum())
            assert (infos["episode"]["l"][infos["_episode"]] == 10).all()
    assert episodes == 8


def test_dict_info_to_list_wrapper(make_vec) -> None:
    env = DictInfoToList(make_vec(2, max_steps=3, autoreset_mode="same_step"))
    _, infos = env.reset(seed=0)
    assert isinstance(infos, list) and len(infos) == 2 and "seed" in infos[0]
    for _ in range(3):
        *_, infos = env.step(np.zeros(2, np.int64))
    assert all("final_obs" in info and info["final_info"]["episode_length"] == 3 for info in infos)


def test_workers_are_the_extension_module(make_vec) -> None:
    env = make_vec(4, num_workers=2)
    for pid in env.worker_pids:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            argv = f.read().split(b"\0")
        assert b"rogue_gym.worker" in argv and b"-m" in argv


@pytest.mark.parametrize("mode", ["next_step", "same_step"])
def test_same_trajectories_for_1_2_3_4_5_8_workers(make_vec, mode) -> None:
    """Even and uneven worker blocks (3 and 5 workers for 8 envs) play the same games."""
    acts = _actions(8, 60, seed=1)
    runs = []
    for workers in (1, 2, 3, 4, 5, 8):
        env = make_vec(8, num_workers=workers, max_steps=25, seed=42, autoreset_mode=mode)
        obs, infos = env.reset()
        trace = [obs.copy(), infos["seed"].copy()]
        for a in acts:
            obs, rew, term, trunc, infos = env.step(a)
            trace += [obs.copy(), rew, term, trunc, infos["seed"].copy()]
        runs.append(trace)
        env.close()
    for other in runs[1:]:
        assert all(np.array_equal(x, y) for x, y in zip(runs[0], other))


def test_pool_matches_single_env(make_vec) -> None:
    env = make_vec(2, num_workers=1, max_steps=100, seed=9)
    obs, infos = env.reset()
    single = RogueEnv(
        config_dict=PAPER, max_steps=100, obs="symbol_onehot", dtype="uint8", stair_reward=50.0
    )
    s_obs, _ = single.reset(seed=int(infos["seed"][1]))
    assert np.array_equal(obs[1], s_obs)
    for a in _actions(2, 40, seed=5):
        obs, rew, *_ = env.step(a)
        s_obs, s_rew, *_ = single.step(int(a[1]))
        assert np.array_equal(obs[1], s_obs) and rew[1] == s_rew


def test_reset_with_seed_reproduces(make_vec) -> None:
    env = make_vec(4, max_steps=50)
    a, ia = env.reset(seed=5)
    a = a.copy()
    for act in _actions(4, 10):
        env.step(act)
    b, ib = env.reset(seed=5)
    assert np.array_equal(a, b) and np.array_equal(ia["seed"], ib["seed"])
    c, ic = env.reset()
    assert not np.array_equal(ia["seed"], ic["seed"])  # next episodes
    env.reset(options={"reset_mask": np.ones(4, bool)})


def test_seed_list_and_sequential_policy(make_vec) -> None:
    env = make_vec(4, seeds=range(1000, 1004), seed_policy="sequential", max_steps=5)
    _, infos = env.reset()
    assert sorted(infos["seed"].tolist()) == [1000, 1001, 1002, 1003]


@pytest.mark.parametrize("policy", ["sample", "sequential"])
def test_shards_together_play_what_the_whole_pool_plays(make_vec, policy: str) -> None:
    # One pool per machine (rogue_gym.ray): pools holding envs [0, 2) and [2, 7) of 7.
    kw = {"seeds": range(100, 105), "seed_policy": policy, "max_steps": 20, "seed": 9}
    whole = make_vec(7, num_workers=2, **kw)
    parts = [make_vec(2, num_workers=1, shard=(0, 7), **kw), make_vec(5, shard=(2, 7), **kw)]
    got = [p.reset(seed=3) for p in parts]
    want = whole.reset(seed=3)
    assert np.array_equal(np.concatenate([g[0] for g in got]), want[0])
    for act in _actions(7, 60):
        x = whole.step(act)
        ys = [parts[0].step(act[:2]), parts[1].step(act[2:])]
        for k in range(4):
            assert np.array_equal(np.concatenate([y[k] for y in ys]), x[k])
        assert np.array_equal(np.concatenate([y[4]["seed"] for y in ys]), x[4]["seed"])
    with pytest.raises(ValueError, match="shard"):
        make_vec(4, shard=(5, 7))


def test_double_buffer_keeps_previous_observation(make_vec) -> None:
    env = make_vec(4, max_steps=50)
    prev, _ = env.reset(seed=0)
    # The sync batch is written by the workers straight into the pool's shared buffer (no copy).
    ptr = prev.__array_interface__["data"][0]
    assert any(lo <= ptr < hi for lo, hi, _ in _batch_ranges())
    prev_copy = prev.copy()
    for a in _actions(4, 20):
        obs, *_ = env.step(a)
        assert obs is not prev
        assert np.array_equal(prev, prev_copy), "step t+1 overwrote the array returned at step t"
        prev, prev_copy = obs, obs.copy()


@pytest.mark.parametrize(
    ("actions", "exc", "match"),
    [
        (np.zeros(3, np.int64), ValueError, r"shape \(4,\)"),
        (np.zeros((4, 2), np.int64), ValueError, r"shape \(4,\)"),
        (np.full(4, 0.5), TypeError, "integer actions"),
        (np.array([0, 1, 11, 2]), ValueError, "env 2: action 11 is out of range"),
        (np.array([0, -1, 1, 2]), ValueError, "env 1: action -1 is out of range"),
        (["a", "b", "c", "d"], TypeError, "integer actions"),
        (0, TypeError, "got a scalar"),
    ],
)
def test_bad_actions(make_vec, actions, exc, match) -> None:
    env = make_vec(4)
    env.reset(seed=0)
    with pytest.raises(exc, match=match):
        env.step(actions)
    env.step(np.zeros(4, np.int64))  # still usable


def test_key_string_actions(make_vec) -> None:
    """A key string is one action per env, each key the action of that index (". h j k l n b
    u y > s"): a twin stepped with the indices plays the same."""
    order = ".hjklnbuy>s"
    keys, twin, idle = make_vec(4), make_vec(4), make_vec(4)
    for env in (keys, twin, idle):
        env.reset(seed=0)
    moved = False
    for string in ("hjkl", "lkjh", "nbuy", "ss>."):
        got = keys.step(string)
        want = twin.step(np.array([order.index(c) for c in string], np.int64))
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
        moved |= not np.array_equal(got[0], idle.step("....")[0])
    assert moved, "the keys were applied: the players moved where no-ops leave them"


def test_bad_config_names_the_key() -> None:
    with pytest.raises(ValueError, match="widht"):
        rogue_gym.make_vec(2, config={"widht": 40})
    with pytest.raises(ValueError, match="num_workers"):
        rogue_gym.make_vec(2, num_workers=3)
    with pytest.raises(ValueError, match="on_worker_failure"):
        rogue_gym.make_vec(2, on_worker_failure="ignore")


def test_killed_worker_raises_with_details(make_vec) -> None:
    env = make_vec(4, num_workers=2, on_worker_failure="raise")
    env.reset(seed=0)
    pid = env.worker_pids[0]
    os.kill(pid, signal.SIGKILL)
    with pytest.raises(WorkerCrashedError) as info:
        for a in _actions(4, 50):
            env.step(a)
    err = info.value
    assert err.pid == pid and err.signal == signal.SIGKILL and err.env == 0 and err.envs == (0, 1)
    assert str(pid) in str(err)
    env.reset(seed=0)  # usable again
    env.step(np.zeros(4, np.int64))


def _batch_ranges() -> list[tuple[int, int, str]]:
    """This process's mappings of a pool's batch buffer (a memory file, ipc/src/buffer.rs)."""
    out = []
    with open("/proc/self/maps") as f:
        for line in f:
            parts = line.split()
            if len(parts) >= 6 and parts[5].startswith("/memfd:rogue-gym-batch"):
                lo, hi = (int(x, 16) for x in parts[0].split("-"))
                out.append((lo, hi, parts[5]))
    return out


def test_make_vec_through_gymnasium() -> None:
    env = gym.make_vec("RogueGym-v0", num_envs=2, num_workers=1, seed=0, max_steps=10)
    try:
        assert isinstance(env, rogue_gym.RogueVectorEnv)
        env.reset()
        env.step(np.zeros(2, np.int64))
    finally:
        env.close()


def test_render_call_get_attr(make_vec) -> None:
    env = make_vec(2, num_workers=1, render_mode="ansi", max_steps=30)
    env.reset(seed=4)
    acts = _actions(2, 12, seed=3)
    for a in acts:
        env.step(a)
    frames = env.render()
    assert len(frames) == 2 and all("Level:" in f for f in frames)
    single = RogueEnv(config_dict=PAPER, max_steps=30, render_mode="ansi", stair_reward=50.0)
    single.reset(seed=env.get_attr("episode_seed")[0])
    for a in acts:
        single.step(int(a[0]))
    assert frames[0] == single.render()
    assert env.get_attr("max_steps") == (30, 30)
    assert env.call("render") == frames
    with pytest.raises(AttributeError):
        env.get_attr("nonexistent")


def test_ctrl_c_interrupts_a_stepping_loop(make_vec, sigint_handler) -> None:
    """SIGINT reaches Python while the pool steps (iceoryx2 must not take the handler)."""
    import threading
    import time

    env = make_vec(4, max_steps=100)
    env.reset(seed=0)
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    with pytest.raises(KeyboardInterrupt):
        timer.start()  # inside the block: a loaded machine may stall us for longer than 0.3 s
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            env.step(np.zeros(4, np.int64))
    timer.cancel()
    env.step(np.zeros(4, np.int64))  # still usable after the interrupt


def test_worker_module_rejects_bad_arguments() -> None:
    import subprocess
    import sys

    r = subprocess.run(
        [sys.executable, "-m", "rogue_gym.worker", "--bogus"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2 and "usage" in r.stderr


def test_worker_that_cannot_start_reports_its_stderr() -> None:
    import sys

    bad = [
        sys.executable,
        "-c",
        "import sys; sys.stderr.write('boom from the worker'); sys.exit(3)",
    ]
    with pytest.raises(RuntimeError, match="boom from the worker"):
        rogue_gym.make_vec(2, num_workers=1, seed=0, worker_command=bad)


def test_async_matches_sync_trajectories(make_vec) -> None:
    acts = _actions(4, 30, seed=7)
    sync = make_vec(4, num_workers=2, max_steps=12, seed=3)
    obs, _ = sync.reset()
    want = [obs.copy()]
    for a in acts:
        want.append(sync.step(a)[0].copy())
    env = make_vec(4, num_workers=2, max_steps=12, seed=3, batch_size=2)
    env.async_reset()
    got: dict[int, list[np.ndarray]] = {i: [] for i in range(4)}
    while min(len(v) for v in got.values()) <= len(acts):
        obs, _, _, _, infos = env.recv()  # the first two envs ready, of any workers
        ids = infos["env_id"]
        for r, i in enumerate(ids):
            got[int(i)].append(obs[r].copy())
        # Each env's next action by its own count (envs of one batch may differ).
        t = [min(len(got[int(i)]) - 1, len(acts) - 1) for i in ids]
        env.send(np.array([acts[ti][i] for ti, i in zip(t, ids)]), ids)
    for i in range(4):
        for t in range(len(acts) + 1):
            assert np.array_equal(got[i][t], want[t][i]), (i, t)


def _run(env, acts, mask_at=None, mask=None):
    """Reset, step through ``acts`` (partial reset with ``mask`` after step ``mask_at``)."""
    obs, infos = env.reset()
    frames = [(obs.copy(), None, None, None, {k: np.copy(v) for k, v in infos.items()})]
    for t, a in enumerate(acts):
        obs, rew, term, trunc, infos = env.step(a)
        frames.append((obs.copy(), rew, term, trunc, {k: np.copy(v) for k, v in infos.items()}))
        if t == mask_at:
            obs, infos = env.reset(options={"reset_mask": mask})
            frames.append((obs.copy(), None, None, None, {k: np.copy(v) for k, v in infos.items()}))
    return frames


def test_partial_reset_mask_follows_gymnasium(make_vec) -> None:
    n, at = 4, 7
    mask = np.array([True, False, False, True])
    acts = _actions(n, 20, seed=3)
    ref = _run(make_vec(n, num_workers=2, max_steps=6, seed=11), acts)
    run = _run(make_vec(n, num_workers=2, max_steps=6, seed=11), acts, at, mask)
    before, reset = run[at + 1], run[at + 2]
    obs, infos = reset[0], reset[4]
    # Infos only for the reset envs, with the mask in every _key array.
    assert set(infos) >= INFO_KEYS
    for key in INFO_KEYS:
        assert np.array_equal(infos[f"_{key}"], mask), key
        assert (infos[key][~mask] == 0).all(), key
    assert (infos["episode_length"][mask] == 0).all()
    assert np.array_equal(infos["episode_index"][mask], before[4]["episode_index"][mask] + 1)
    # Unmasked envs: observation unchanged, and they continue as if nothing happened.
    assert np.array_equal(obs[~mask], before[0][~mask])
    for t in range(len(ref)):
        r = ref[t]
        f = run[t if t <= at + 1 else t + 1]
        assert np.array_equal(r[0][~mask], f[0][~mask]), t
        if r[1] is not None:
            for k in (1, 2, 3):
                assert np.array_equal(r[k][~mask], f[k][~mask]), (t, k)
            for key in INFO_KEYS:
                assert np.array_equal(r[4][key][~mask], f[4][key][~mask]), (t, key)
    # The masked envs played their next episode.
    assert any(
        not np.array_equal(ref[t][0][mask], run[t + 1][0][mask]) for t in range(at + 2, len(ref))
    )


def test_partial_reset_is_the_same_for_one_and_two_workers(make_vec) -> None:
    mask = np.array([False, True, True, False])
    acts = _actions(4, 15, seed=4)
    runs = [_run(make_vec(4, num_workers=w, max_steps=5, seed=2), acts, 6, mask) for w in (1, 2)]
    for a, b in zip(*runs):
        for x, y in zip(a[:4], b[:4]):
            assert (x is None and y is None) or np.array_equal(x, y)
        assert a[4].keys() == b[4].keys()
        assert all(np.array_equal(a[4][k], b[4][k]) for k in a[4])


@pytest.mark.parametrize("kind", ["native", "hosted"])
@pytest.mark.parametrize(
    ("mask", "error", "message"),
    [
        (np.array([True, False, True]), ValueError, "must have shape `(4,)`, got (3,)"),
        (np.ones((4, 1), bool), ValueError, "must have shape `(4,)`, got (4, 1)"),
        (np.array([1, 0, 1, 0]), TypeError, "must have `dtype=np.bool_`, got int64"),
        (np.array([1.0, 0.0, 1.0, 0.0]), TypeError, "must have `dtype=np.bool_`, got float64"),
        ([True, False, True, False], TypeError, "must be a numpy array, got <class 'list'>"),
        (np.zeros(4, bool), ValueError, "must contain a boolean array with at least one True"),
    ],
)
def test_bad_reset_masks_raise_gymnasiums_errors(kind, make_vec, mask, error, message) -> None:
    """Both kinds check ``reset_mask`` as gymnasium's vector envs do (types and messages)."""
    env = make_kind(kind, make_vec)
    try:
        env.reset(seed=1)
        with pytest.raises(error, match=re.escape(f"`options['reset_mask']` {message}")):
            env.reset(options={"reset_mask": mask})
        env.step(env.action_space.sample())  # still usable
    finally:
        if kind == "hosted":  # the fixture closes the native pool and checks for leaks
            env.close()


@pytest.mark.parametrize("kind", ["native", "hosted"])
def test_a_partial_reset_needs_a_full_one_first(kind, make_vec) -> None:
    """Before the first full reset a partial mask is refused; a mask of every env is a full
    reset."""
    env = make_kind(kind, make_vec)
    try:
        with pytest.raises(ValueError, match="needs a full reset"):
            env.reset(options={"reset_mask": np.array([True, False, False, False])})
        env.reset(options={"reset_mask": np.ones(4, bool)})
        env.step(env.action_space.sample())
    finally:
        if kind == "hosted":  # the fixture closes the native pool and checks for leaks
            env.close()


def make_kind(kind: str, make_vec) -> rogue_gym.vector.RogueVectorEnv | rogue_gym.PoolVectorEnv:
    """4 envs of the native game (closed and leak-checked by the fixture) or of hosted
    CartPole."""
    if kind == "native":
        return make_vec(4, num_workers=2)
    return rogue_gym.PoolVectorEnv([lambda: gym.make("CartPole-v1")] * 4, num_workers=2)


def test_partial_reset_rules(make_vec) -> None:
    env = make_vec(4, num_workers=2, max_steps=3)
    m = np.array([True, False, False, False])
    with pytest.raises(ValueError, match="needs a full reset"):
        env.reset(options={"reset_mask": m})
    env.reset(seed=1)
    with pytest.raises(ValueError, match="seed"):
        env.reset(seed=2, options={"reset_mask": m})
    # An unmasked env whose episode ended is still autoreset by the next step.
    for _ in range(3):
        *_, trunc, infos = env.step(np.zeros(4, np.int64))
    assert trunc.all()
    obs, infos = env.reset(options={"reset_mask": m})
    assert infos["episode_index"][0] == 1 and infos["episode_length"][0] == 0
    obs, rew, term, trunc, infos = env.step(np.zeros(4, np.int64))
    assert (infos["episode_index"] == 1).all() and (infos["episode_length"][1:] == 0).all()
    assert infos["episode_length"][0] == 1 and (rew[1:] == 0).all()


@pytest.mark.parametrize("mode", ["next_step", "same_step"])
def test_step_reset_and_recv_return_one_result_form(make_vec, mode) -> None:
    """Every call's result is decoded the same way: a trajectory stepped with reset/step and
    the same one through async_reset/send/recv (rows put back in env order) give the same
    observations, rewards, flags and infos, dtypes included."""
    synced = make_vec(4, num_workers=2, max_steps=7, autoreset_mode=mode, seed=3)
    pooled = make_vec(4, num_workers=2, max_steps=7, autoreset_mode=mode, seed=3)

    def in_env_order(out):
        obs, rew, term, trunc, infos = out
        order = np.argsort(infos["env_id"])
        return (obs[order], rew[order], term[order], trunc[order]), {
            k: v[order] for k, v in infos.items() if k != "env_id"
        }

    want = synced.reset()
    pooled.async_reset()
    got = in_env_order(pooled.recv())
    assert np.array_equal(got[0][0], want[0])
    skip = ("final_obs", "_final_obs", "final_info", "_final_info")
    for t, a in enumerate(_actions(4, 40, seed=8)):
        obs, rew, term, trunc, infos = synced.step(a)
        pooled.send(a, np.arange(4))
        (g_obs, g_rew, g_term, g_trunc), g_infos = in_env_order(pooled.recv())
        assert np.array_equal(g_obs, obs) and np.array_equal(g_rew, rew), t
        assert g_rew.dtype == rew.dtype == np.float64 and g_term.dtype == np.bool_
        assert np.array_equal(g_term, term) and np.array_equal(g_trunc, trunc), t
        assert sorted(g_infos) == sorted(k for k in infos if k not in skip), t
        for key, arr in g_infos.items():
            assert arr.dtype == infos[key].dtype and np.array_equal(arr, infos[key]), (t, key)


def test_step_info_arrays_live_until_the_second_following_step(make_vec) -> None:
    env = make_vec(4, num_workers=2, max_steps=5, seed=1)
    env.reset()
    acts = _actions(4, 12, seed=2)
    *_, prev = env.step(acts[0])
    kept = {k: v.copy() for k, v in prev.items()}
    for a in acts[1:]:
        *_, infos = env.step(a)
        assert infos["seed"] is not prev["seed"]
        assert all(np.array_equal(prev[k], kept[k]) for k in kept), "step t+1 overwrote step t"
        prev, kept = infos, {k: v.copy() for k, v in infos.items()}
    fresh = make_vec(4, num_workers=2, max_steps=5, seed=1, copy=True)
    fresh.reset()
    seen = [fresh.step(a)[4]["episode_length"] for a in acts[:6]]
    assert [int(x[0]) for x in seen] == [1, 2, 3, 4, 5, 0]  # none rewritten later


def test_render_replay_follows_a_partial_reset(make_vec) -> None:
    mask = np.array([True, False, True, False])
    acts = _actions(4, 14, seed=6)
    screens = []
    for m in (None, mask):
        env = make_vec(4, num_workers=2, max_steps=4, seed=5, render_mode="ansi")
        env.reset()
        for t, a in enumerate(acts):
            env.step(a)
            # The episode log follows every env's episode (length as the columns say).
            cols = env._core.cols[env._core.state.slot]
            assert np.array_equal(env._core.state.log.length, cols["episode_length"]), t
            if m is not None and t == 3:  # all envs just ended: unmasked ones autoreset next
                env.reset(options={"reset_mask": m})
        screens.append(env.render())
    for i in np.flatnonzero(~mask):
        assert screens[0][i] == screens[1][i]


def test_ctrl_c_interrupts_a_long_wait_and_reset_recovers(make_vec, sigint_handler) -> None:
    """SIGINT during a wait for a stopped worker raises KeyboardInterrupt from step() at once
    (the pool runs the signal handlers between wait slices), not after step_timeout."""
    import threading
    import time

    # The step timeout bounds the wait even if the interrupt were lost (then the worker is
    # restarted and the assertions below fail instead of the suite hanging).
    env = make_vec(4, num_workers=2, step_timeout=60.0)
    env.reset(seed=0)
    pid = env.worker_pids[0]
    os.kill(pid, signal.SIGSTOP)
    try:
        timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
        t0 = time.monotonic()
        with pytest.raises(KeyboardInterrupt):
            timer.start()
            env.step(np.zeros(4, np.int64))  # waits for the stopped worker
        assert time.monotonic() - t0 < 20
    finally:
        timer.cancel()
        os.kill(pid, signal.SIGCONT)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(4, np.int64))
    env.reset()
    obs, rew, term, trunc, infos = env.step(np.zeros(4, np.int64))
    assert (infos["episode_length"] == 1).all()
    assert env.worker_pids[0] == pid  # the worker was not restarted


@pytest.mark.parametrize("kind", ["native", "hosted"])
def test_a_closed_pool_raises_gymnasiums_closed_error(kind, make_vec) -> None:
    """Every kind raises gymnasium's ``ClosedEnvironmentError`` (still a ``RuntimeError``)
    with one message, from Python and from the native pool alike."""
    env = make_kind(kind, make_vec)
    env.reset(seed=0)
    native = env._core.pool
    env.close()
    for call in (
        env.reset,
        lambda: env.step(env.action_space.sample()),
        lambda: native.select_slot(0),
    ):
        with pytest.raises(ClosedEnvironmentError, match="the pool is closed") as info:
            call()
        assert isinstance(info.value, RuntimeError), "still what it was before"
        assert isinstance(info.value, rogue_gym.PoolClosedError)


@pytest.mark.parametrize("kind", ["native", "hosted"])
def test_disabled_autoreset_waits_for_a_reset_mask(kind, make_vec) -> None:
    """``AutoresetMode.DISABLED`` in both kinds: a finished env is not stepped until a
    ``reset_mask`` resets it (stepping it is a ``ValueError`` naming it); the others go on."""
    mode = AutoresetMode.DISABLED
    if kind == "native":
        env = make_vec(4, num_workers=2, max_steps=3, autoreset_mode=mode)
    else:
        env = rogue_gym.PoolVectorEnv(
            [lambda: gym.make("CartPole-v1")] * 4, num_workers=2, autoreset_mode=mode
        )
    try:
        assert env.metadata["autoreset_mode"] == mode
        env.reset(seed=0)
        env.action_space.seed(0)
        done = np.zeros(4, bool)
        for _ in range(500):
            last, _, term, trunc, _ = env.step(env.action_space.sample())
            done = term | trunc
            if done.any():
                break
        assert done.any()
        finished = np.flatnonzero(done).tolist()
        with pytest.raises(ValueError, match=re.escape(f"envs {finished} finished their episode")):
            env.step(env.action_space.sample())
        obs, _ = env.reset(options={"reset_mask": done})
        assert np.array_equal(obs[~done], last[~done]), "the others keep their state"
        env.step(env.action_space.sample())  # every env may step again
    finally:
        if kind == "hosted":
            env.close()


@pytest.mark.parametrize("kind", ["native", "hosted"])
def test_the_split_async_api_matches_step_and_reset(kind, make_vec) -> None:
    """``reset_async``/``reset_wait``, ``step_async``/``step_wait`` and ``call_async``/
    ``call_wait`` give what ``reset``, ``step`` and ``call`` give, in both kinds, and calls out
    of order raise gymnasium's errors."""
    from gymnasium.error import AlreadyPendingCallError, NoAsyncCallError

    split, plain = make_kind(kind, make_vec), make_kind(kind, make_vec)
    try:
        with pytest.raises(NoAsyncCallError, match=re.escape("Calling `step_wait` without")):
            split.step_wait()
        split.reset_async(seed=3)
        with pytest.raises(AlreadyPendingCallError, match="pending call to `reset`"):
            split.step_async(split.action_space.sample())
        with pytest.raises(AlreadyPendingCallError, match="pending call to `reset`"):
            split.reset_async()
        obs, _ = split.reset_wait()
        assert np.array_equal(obs, plain.reset(seed=3)[0])
        rng = np.random.default_rng(0)
        for _ in range(30):
            actions = rng.integers(0, split.single_action_space.n, 4)
            split.step_async(actions)
            with pytest.raises(NoAsyncCallError, match="`reset_wait` without"):
                split.reset_wait()
            got, want = split.step_wait(), plain.step(actions)
            for a, b in zip(got[:4], want[:4]):
                assert np.array_equal(a, b)
        # call_async/call_wait: the results call gives; a pending call refuses other calls.
        with pytest.raises(NoAsyncCallError, match="`call_wait` without"):
            split.call_wait()
        split.call_async("render_mode")
        with pytest.raises(AlreadyPendingCallError, match="pending call to `call`"):
            split.get_attr("render_mode")
        assert split.call_wait(timeout=1) == plain.call("render_mode")
        split.call_async("no_such_attribute")
        with pytest.raises(AttributeError):
            split.call_wait()
        split.step_async(split.action_space.sample())
        with pytest.raises(AlreadyPendingCallError, match="pending call to `step`"):
            split.call_async("render_mode")
        with pytest.warns(UserWarning, match="while waiting for a pending call to `step`"):
            split.close()
    finally:
        if kind == "hosted":
            for env in (split, plain):
                env.close()


class SlowEnv(gym.Env):
    """Sleeps 0.2 s per step."""

    observation_space = gym.spaces.Box(0, 1, (2,))
    action_space = gym.spaces.Discrete(2)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.zeros(2, np.float32), {}

    def step(self, action):
        import time

        time.sleep(0.2)
        return np.zeros(2, np.float32), 1.0, False, False, {}


def test_step_wait_times_out_and_the_step_stays_pending() -> None:
    import multiprocessing as mp
    import time

    env = rogue_gym.PoolVectorEnv([SlowEnv] * 2, num_workers=2)
    try:
        env.reset(seed=0)
        start = time.monotonic()
        env.step_async(np.zeros(2, np.int64))
        assert time.monotonic() - start < 0.1, "step_async returns before the envs step"
        with pytest.raises(mp.TimeoutError, match=re.escape("timed out after 0.05 second")):
            env.step_wait(timeout=0.05)
        _, rewards, *_ = env.step_wait(timeout=5)
        assert rewards.tolist() == [1.0, 1.0]
    finally:
        env.close()
