"""``rogue_gym.envpool``: EnvPool's API over gymnasium envs, as EnvPool-style scripts (CleanRL's
``ppo_atari_envpool.py`` and its async variants) use it; compared with EnvPool itself where it
is installed."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import rogue_gym.envpool as envpool
from gymnasium.vector import SyncVectorEnv


@pytest.fixture
def make() -> Any:
    made: list[envpool.EnvPoolEnv] = []

    def factory(*args: Any, **kwargs: Any) -> envpool.EnvPoolEnv:
        envs = envpool.make(*args, **kwargs)
        made.append(envs)
        return envs

    yield factory
    for envs in made:
        envs.close()


def test_sync_steps_are_gymnasiums_with_envpools_infos(make) -> None:
    """Single-env spaces, float32 rewards, bool flags, int32 env_id/players/elapsed_step; the
    games are those of SyncVectorEnv seeded ``seed + i``, EnvPool's autoreset included (the
    step after an end starts the next episode, elapsed_step 0)."""
    envs = make("CartPole-v1", num_envs=4, seed=3, max_episode_steps=20)
    ref = SyncVectorEnv([lambda: gym.make("CartPole-v1", max_episode_steps=20)] * 4)
    assert envs.observation_space == ref.single_observation_space
    assert envs.action_space == gym.spaces.Discrete(2) and len(envs) == 4
    assert envs.spec.config.max_episode_steps == 20 and envs.spec.config.seed == 3
    assert envs.config["num_envs"] == 4 and not envs.is_async
    obs, info = envs.reset()
    ref_obs, _ = ref.reset(seed=3)
    np.testing.assert_array_equal(obs, ref_obs)
    assert info["env_id"].dtype == np.int32 and list(info["env_id"]) == [0, 1, 2, 3]
    assert info["players"]["env_id"].dtype == np.int32
    assert list(info["elapsed_step"]) == [0] * 4
    elapsed = np.zeros(4, np.int32)
    ended = np.zeros(4, bool)
    rng = np.random.default_rng(0)
    saw_end = False
    for _ in range(60):
        actions = rng.integers(0, 2, 4)
        obs, reward, terminated, truncated, info = envs.step(actions)
        ref_out = ref.step(actions)
        np.testing.assert_array_equal(obs, ref_out[0])
        np.testing.assert_array_equal(reward, ref_out[1].astype(np.float32))
        np.testing.assert_array_equal(terminated, ref_out[2])
        np.testing.assert_array_equal(truncated, ref_out[3])
        assert reward.dtype == np.float32 and terminated.dtype == truncated.dtype == np.bool_
        elapsed = np.where(ended, 0, elapsed + 1)
        ended = terminated | truncated
        saw_end |= bool(ended.any())
        np.testing.assert_array_equal(info["elapsed_step"], elapsed)
        assert info["elapsed_step"].dtype == np.int32
    assert saw_end
    ref.close()


def test_the_gym_type_is_the_four_tuple_api_cleanrl_scripts_use(make) -> None:
    envs = make("CartPole-v1", env_type="gym", num_envs=2, seed=0, max_episode_steps=5)
    obs = envs.reset()
    assert obs.shape == (2, 4)
    dones = []
    for _ in range(6):
        obs, reward, done, info = envs.step(np.zeros(2, np.int64))
        dones.append(done.copy())
        assert done.dtype == np.bool_ and info["TimeLimit.truncated"].dtype == np.bool_
    assert np.array(dones)[4].all(), "the time limit ends both episodes at step 5"


class RecordEpisodeStatistics(gym.Wrapper):
    """The shape of CleanRL's wrapper in its EnvPool scripts (written here, not copied): a
    gymnasium Wrapper over the pool that steps it in its constructor and adds to its infos."""

    def __init__(self, env: Any) -> None:
        super().__init__(env)
        self.num_envs = getattr(env, "num_envs", 1)
        env.reset()
        env.step(np.zeros(self.num_envs, dtype=int))

    def reset(self, **kwargs: Any) -> Any:
        self.returns = np.zeros(self.num_envs, np.float32)
        return super().reset(**kwargs)

    def step(self, action: Any) -> Any:
        obs, rewards, dones, infos = super().step(action)
        self.returns += rewards
        infos["r"] = self.returns.copy()
        self.returns *= 1 - dones
        return obs, rewards, dones, infos


def test_a_cleanrl_style_script_runs(make) -> None:
    """Attributes set on the env (as CleanRL does), a gymnasium Wrapper around it, reset and
    step through the wrapper."""
    envs = make("CartPole-v1", env_type="gym", num_envs=4, seed=1)
    envs.num_envs = 4
    envs.single_action_space = envs.action_space
    envs.single_observation_space = envs.observation_space
    wrapped = RecordEpisodeStatistics(envs)
    assert isinstance(wrapped.action_space, gym.spaces.Discrete)
    obs = wrapped.reset()
    assert obs.shape == (4, *envs.single_observation_space.shape)
    for _ in range(50):
        obs, rewards, dones, infos = wrapped.step(np.ones(4, np.int64))
    assert infos["r"].shape == (4,) and "lives" not in infos


def _per_env_runs(recv_send: Any, num_envs: int, steps: int) -> dict[int, list[np.ndarray]]:
    """Observations per env over ``steps`` of its own, each env stepping ``(e + k) % 2`` at
    its k-th step, whatever the order of service."""
    seen: dict[int, list[np.ndarray]] = {e: [] for e in range(num_envs)}
    recv, send = recv_send
    while min(len(v) for v in seen.values()) < steps:
        obs, _, _, _, info = recv()
        ids = info["env_id"]
        for row, e in enumerate(ids):
            seen[int(e)].append(obs[row].copy())
        send(np.array([(int(e) + len(seen[int(e)])) % 2 for e in ids]), ids)
    return {e: v[:steps] for e, v in seen.items()}


def test_async_batches_serve_any_env_and_keep_each_envs_game(make) -> None:
    """batch_size < num_envs: recv returns batch_size envs with their ids, send answers them;
    each env plays the game it plays when every env is stepped at once."""
    steps = 30
    envs = make("CartPole-v1", num_envs=8, batch_size=4, num_threads=2, seed=5)
    assert envs.is_async and envs.pool.num_workers >= 2
    envs.async_reset()
    ours = _per_env_runs((envs.recv, envs.send), 8, steps)
    sync = make("CartPole-v1", num_envs=8, seed=5)
    first, info = sync.reset()
    state = {"obs": first, "count": np.zeros(8, int)}

    def recv() -> Any:
        return state["obs"], None, None, None, {"env_id": np.arange(8, dtype=np.int32)}

    def send(actions: Any, ids: Any) -> None:
        state["obs"] = sync.step(actions)[0]

    ref = _per_env_runs((recv, send), 8, steps)
    for e in range(8):
        np.testing.assert_array_equal(np.array(ours[e]), np.array(ref[e]), err_msg=f"env {e}")


def test_bad_arguments_say_what_to_do(make) -> None:
    with pytest.raises(ValueError, match="env_type"):
        make("CartPole-v1", env_type="dm")
    with pytest.raises(ValueError, match="batch_size"):
        make("CartPole-v1", num_envs=2, batch_size=3)
    envs = make("CartPole-v1", num_envs=2)
    with pytest.raises(RuntimeError, match="reset"):
        envs.step(np.zeros(2, np.int64))
    envs.reset()
    with pytest.raises(ValueError, match="smaller batch_size"):
        envs.step(np.zeros(1, np.int64), env_id=np.array([0]))


def test_atari_ids_take_envpools_preprocessing(make) -> None:
    """Pong-v5 through ale-py's vector env: EnvPool's 4x84x84 stacked frames, its Atari infos,
    and reward_clip clipping the reward while info["reward"] keeps the raw one."""
    pytest.importorskip("ale_py")
    envs = make("Pong-v5", num_envs=2, reward_clip=True, seed=0)
    assert envs.observation_space == gym.spaces.Box(0, 255, (4, 84, 84), np.uint8)
    assert envs.action_space == gym.spaces.Discrete(6)
    assert envs.spec.config.stack_num == 4 and envs.spec.config.task == "pong"
    obs, info = envs.reset()
    assert obs.shape == (2, 4, 84, 84) and obs.dtype == np.uint8
    scored = False
    for _ in range(300):
        obs, reward, terminated, truncated, info = envs.step(np.zeros(2, np.int64))
        assert info["lives"].dtype == np.int32 and info["terminated"].dtype == np.int32
        np.testing.assert_array_equal(reward, np.sign(info["reward"]))
        scored |= bool(np.abs(info["reward"]).sum() > 0)
    assert scored, "Pong scores within 300 steps"


@pytest.mark.parametrize("task_id", ["CartPole-v1", "Pong-v5"])
def test_the_surface_matches_envpools(make, task_id) -> None:
    """Where EnvPool is installed: the same spaces, output dtypes and shapes, info keys and
    dtypes (EnvPool's Atari "ram" aside, which ale-py's vector env does not give), and config
    fields."""
    real = pytest.importorskip("envpool")
    if task_id == "Pong-v5":
        pytest.importorskip("ale_py")
    theirs = real.make(task_id, env_type="gymnasium", num_envs=2, seed=0)
    ours = make(task_id, env_type="gymnasium", num_envs=2, seed=0)
    try:
        assert ours.observation_space == theirs.observation_space
        assert ours.action_space == theirs.action_space
        r_ours, r_theirs = ours.reset(), theirs.reset()
        s_ours = ours.step(np.zeros(2, np.int32))
        s_theirs = theirs.step(np.zeros(2, np.int32))
        for a, b in zip(s_ours[:4], s_theirs[:4]):
            assert (a.dtype, a.shape) == (b.dtype, b.shape)
        for (_, mine), (_, ref) in ((r_ours, r_theirs), (s_ours[:5:4], s_theirs[:5:4])):
            for key, value in ref.items():
                if key == "ram":
                    continue
                assert key in mine, key
                if isinstance(value, dict):
                    assert mine[key]["env_id"].dtype == value["env_id"].dtype
                else:
                    assert (mine[key].dtype, mine[key].shape) == (value.dtype, value.shape), key
        ours_fields = set(ours.spec.config._fields)
        for name in ("num_envs", "batch_size", "num_threads", "max_num_players", "seed"):
            assert name in ours_fields and name in theirs.spec.config._fields
        assert ours.spec.config.max_episode_steps == theirs.spec.config.max_episode_steps
    finally:
        theirs.close()
