"""The pool as a Stable-Baselines3 VecEnv: API, episode ends, rollout buffers, PPO."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stable_baselines3.common.vec_env import VecEnv


def test_is_a_vec_env_with_sb3_api(make_sb3) -> None:
    env = make_sb3(4, obs="symbol_index", max_steps=20)
    assert isinstance(env, VecEnv)
    assert env.observation_space.shape == (16, 32)
    assert env.seed(7) == [7, 8, 9, 10]
    obs = env.reset()
    assert obs.shape == (4, 16, 32)
    assert len(env.reset_infos) == 4 and "seed" in env.reset_infos[0]
    env.step_async(np.zeros(4, np.int64))
    obs, rewards, dones, infos = env.step_wait()
    assert rewards.dtype == np.float32 and dones.dtype == np.bool_ and len(infos) == 4
    assert env.get_attr("max_steps") == [20] * 4
    assert env.get_attr("render_mode") == [None] * 4
    assert env.env_is_wrapped(object) == [False] * 4
    with pytest.raises(NotImplementedError, match=r"the native game does not serve .*setattr"):
        env.set_attr("max_steps", 3)
    with pytest.raises(AttributeError):
        env.env_method("nope")


def test_seed_then_reset_is_reproducible(make_sb3) -> None:
    env = make_sb3(4, max_steps=20)
    env.seed(3)
    a = env.reset().copy()
    env.step(np.ones(4, np.int64))
    env.seed(3)
    b = env.reset()
    assert np.array_equal(a, b)


def test_terminal_observation_and_time_limit(make_sb3) -> None:
    env = make_sb3(4, max_steps=5)
    obs = env.reset()
    for _ in range(5):
        last = obs.copy()
        obs, rewards, dones, infos = env.step(np.zeros(4, np.int64))
    assert dones.all()
    for i, info in enumerate(infos):
        assert info["TimeLimit.truncated"] is True
        assert np.array_equal(info["terminal_observation"], last[i])  # no-ops: same screen
        assert info["episode"]["l"] == 5
    assert all(inf.get("episode_index") == 0 for inf in infos)


def test_rollout_double_buffering(make_sb3) -> None:
    """SB3 keeps the previous obs while stepping: it must not change under it."""
    env = make_sb3(4, max_steps=7)
    last = env.reset()
    snapshot = last.copy()
    rng = np.random.default_rng(0)
    for _ in range(30):
        new, _, _, _ = env.step(rng.integers(0, 11, 4))
        assert np.array_equal(last, snapshot)
        last, snapshot = new, new.copy()


def test_ppo_learns_a_few_steps(make_sb3) -> None:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import Logger

    torch.set_num_threads(1)
    env = make_sb3(4, obs="symbol_index", max_steps=50)
    model = PPO(
        "MlpPolicy", env, n_steps=32, batch_size=64, n_epochs=1, seed=0, device="cpu", verbose=0
    )
    model.set_logger(Logger(None, []))  # SB3's default logger leaves a folder in /tmp
    model.learn(total_timesteps=512)
    assert model.num_timesteps >= 512
    assert len(model.ep_info_buffer) > 0  # episodes reported through infos["episode"]


def test_get_images_and_render(make_sb3) -> None:
    env = make_sb3(2, num_workers=1, render_mode="rgb_array", max_steps=20)
    env.reset()
    env.step(np.array([4, 2]))
    images = env.get_images()
    assert len(images) == 2 and images[0].shape[0] == 17 and images[0].shape[2] == 3
    assert images[0].shape[1] >= 32 and images[0].dtype == np.uint8
    # Each env renders in its render mode, as gymnasium envs do: images here, text in "ansi".
    assert all(np.array_equal(a, b) for a, b in zip(env.env_method("render"), images))
    assert env.render().ndim == 3  # SB3 tiles the images
    text = make_sb3(2, num_workers=1, render_mode="ansi", max_steps=20)
    text.reset()
    text.step(np.array([4, 2]))
    assert all("Level:" in s for s in text.env_method("render"))
