"""RogueEnv: gymnasium conformance, the original API, wrappers, errors."""

from __future__ import annotations

import io
import json
import warnings

import gymnasium as gym
import numpy as np
import pytest
import rogue_gym
from gymnasium.utils.env_checker import check_env
from rogue_gym.envs import (
    ACTIONS,
    DungeonType,
    FirstFloorEnv,
    ImageSetting,
    RogueEnv,
    StairRewardEnv,
    StatusFlag,
)

PAPER = rogue_gym.PAPER_CONFIG


def _check(env: gym.Env) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # The original API's sticky seed() is kept on purpose.
        warnings.filterwarnings("ignore", message=".*`seed` function is dropped")
        check_env(env, skip_render_check=True)


def test_check_env_default_original_observation() -> None:
    env = RogueEnv()
    assert env.observation_space.shape == (43 + 9, 24, 80)
    assert env.observation_space.dtype == np.float32
    _check(env)


@pytest.mark.parametrize("obs", ["symbol_onehot", "symbol_index", "gray", "ascii", "status"])
@pytest.mark.parametrize("dtype", ["uint8", "float32"])
def test_check_env_encodings(obs: str, dtype: str) -> None:
    _check(RogueEnv(config_dict=PAPER, obs=obs, dtype=dtype, status=StatusFlag.FULL, history=True))


def test_check_env_with_render_through_make() -> None:
    env = gym.make("RogueGym-v0", config_dict=PAPER, max_steps=50, render_mode="ansi")
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*`seed` function is dropped")
        check_env(env.unwrapped)
    env.close()


def test_paper_observation_shape() -> None:
    env = RogueEnv(
        config_dict=PAPER, max_steps=500, image_setting=ImageSetting(status=StatusFlag.EMPTY)
    )
    obs, info = env.reset(seed=1)
    assert obs.shape == (17, 16, 32) and obs.dtype == np.float32
    assert obs[:, 1:-1].sum(axis=0).max() == 1.0  # one-hot in the map rows
    assert ImageSetting(status=StatusFlag.EMPTY).dim(17) == 17
    assert ImageSetting(dungeon=DungeonType.GRAY, includes_hist=True).dim(17) == 1 + 9 + 1
    assert set(info) >= {
        "seed",
        "steps",
        "floor",
        "max_floor",
        "gold",
        "hp",
        "max_hp",
        "died",
        "won",
    }


def test_reset_seed_is_deterministic_and_dungeons_differ() -> None:
    env = RogueEnv(config_dict=PAPER)
    a, _ = env.reset(seed=3)
    b, _ = env.reset(seed=3)
    c, _ = env.reset(seed=4)
    assert np.array_equal(a, b)
    assert env.episode_seed == 4
    assert not np.array_equal(a, c)


def test_seed_range_and_sticky_seed() -> None:
    env = RogueEnv(config_dict=PAPER)
    env.reset(seed=123)
    seeds = {env.reset()[1]["seed"] for _ in range(30)}
    assert seeds <= set(range(40)) and len(seeds) > 5
    env.seed(7)  # original API: every following episode plays dungeon 7
    assert {env.reset()[1]["seed"] for _ in range(3)} == {7}


def test_constructor_does_not_mutate_or_leak_config() -> None:
    cfg = dict(PAPER)
    RogueEnv(config_dict=cfg, hide_dungeon=False)
    assert cfg == PAPER
    assert "hide_dungeon" not in RogueEnv().config  # no shared mutable default


def test_config_path(tmp_path) -> None:
    path = tmp_path / "config.json"
    path.write_text(json.dumps(PAPER))
    env = RogueEnv(config_path=path, max_steps=10)
    assert env.screen_size() == (16, 32)
    env.save_config(tmp_path / "out.json")
    assert json.loads((tmp_path / "out.json").read_text())["width"] == 32


def test_bad_config_names_the_key() -> None:
    with pytest.raises(ValueError, match="widht"):
        RogueEnv(widht=40)
    with pytest.raises(ValueError, match="width"):
        RogueEnv(width=12)
    with pytest.raises(ValueError, match="mex_steps"):
        RogueEnv(config_dict=PAPER, mex_steps=500)  # the paper code's typo is caught now


def test_actions_int_numpy_and_keys() -> None:
    env = RogueEnv(config_dict=PAPER, max_steps=100)
    env.reset(seed=1)
    env.step(3)
    env.step(np.int64(4))
    env.step(np.array(1))
    env.step("hjkl")
    assert env.action_history == "klh" + "hjkl"
    assert env.game.info()["steps"] == 7
    obs, _, _, _, info = env.step("L")  # run: several steps in one call
    assert env.action_history.endswith("L")
    assert info["steps"] >= 8


@pytest.mark.parametrize(
    ("action", "exc", "match"),
    [
        (11, ValueError, "Invalid action: 11"),
        (-1, ValueError, "Invalid action: -1"),
        (1.5, TypeError, "got float"),
        (np.array([1, 2]), TypeError, "shape"),
        ("x", ValueError, "Invalid input key"),
        ("", ValueError, "at least one key"),
        (None, TypeError, "got NoneType"),
    ],
)
def test_bad_actions_raise_clear_errors(action, exc, match) -> None:
    env = RogueEnv(config_dict=PAPER)
    env.reset(seed=0)
    with pytest.raises(exc, match=match):
        env.step(action)


def test_step_before_reset_and_after_end() -> None:
    env = RogueEnv(config_dict=PAPER, max_steps=3)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)
    env.reset(seed=0)
    out = [env.step(0) for _ in range(3)]
    assert [o[3] for o in out] == [False, False, True]
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)


def test_render_modes(capsys) -> None:
    env = RogueEnv(config_dict=PAPER, render_mode="ansi")
    env.reset(seed=2)
    text = env.render()
    assert "@" in text and "Level:" in text.splitlines()[-1]
    assert len(text.splitlines()) == 16 + 1
    human = RogueEnv(config_dict=PAPER, render_mode="human")
    human.reset(seed=2)
    assert human.render() is None
    assert capsys.readouterr().out.strip() == text.strip()
    with pytest.raises(ValueError, match="render_mode"):
        RogueEnv(render_mode="rgb")


def test_save_actions_and_replay(tmp_path) -> None:
    env = RogueEnv(config_dict=PAPER, max_steps=200, render_mode="ansi")
    env.reset(seed=11)
    rng = np.random.default_rng(0)
    for a in rng.integers(0, len(ACTIONS), 40):
        env.step(int(a))
    final = env.render()
    path = tmp_path / "actions.json"
    env.save_actions(path)
    frames = RogueEnv(config_dict=PAPER).replay(0, path=path, out=False)
    assert len(frames) == 41 and frames[-1] == final
    buf = io.StringIO()
    assert env.replay(0, out=buf)[-1] == final
    assert final in buf.getvalue()


def _play_until_descent(env: gym.Env, seed: int, budget: int = 30000):
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    for _ in range(budget):
        before = env.unwrapped.status["dungeon_level"]
        out = env.step(int(rng.integers(0, len(ACTIONS))))
        if env.unwrapped.status["dungeon_level"] > before:
            return out
        if out[2] or out[3]:
            env.reset()
    pytest.fail("no descent within the budget")


def test_stair_reward_wrapper_adds_bonus_once_per_new_floor() -> None:
    plain = RogueEnv(config_dict=PAPER, max_steps=500)
    _, reward, *_ = _play_until_descent(StairRewardEnv(plain, 100.0), seed=5)
    assert reward >= 100.0
    engine = RogueEnv(config_dict=PAPER, max_steps=500, stair_reward=50.0)
    _, reward2, *_ = _play_until_descent(engine, seed=5)
    assert reward2 >= 50.0


def test_first_floor_env_ends_after_descent() -> None:
    env = FirstFloorEnv(RogueEnv(config_dict=PAPER, max_steps=500))
    _, reward, terminated, _, _ = _play_until_descent(env, seed=5)
    assert terminated and reward >= 50.0
    with pytest.raises(TypeError):
        StairRewardEnv(gym.make("CartPole-v1"))


def test_gymnasium_make_registration() -> None:
    env = gym.make("RogueGym-v0", config_dict=PAPER, max_steps=20)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (26, 16, 32)
    assert isinstance(env.unwrapped, RogueEnv)
    env.close()


def test_import_does_not_load_sb3_or_torch() -> None:
    import subprocess
    import sys

    code = "import sys, rogue_gym; assert 'torch' not in sys.modules and 'stable_baselines3' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
    assert rogue_gym.RogueVecEnv.__name__ == "RogueVecEnv"  # lazily importable
