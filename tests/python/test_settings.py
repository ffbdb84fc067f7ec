"""The pool's settings and the package's constants each have one home, and the copies agree."""

from __future__ import annotations

import dataclasses
import inspect
import json

import numpy as np
import pytest
import rogue_gym
from rogue_gym import _native
from rogue_gym.envs import ObsSpec
from rogue_gym.settings import PoolSettings
from rogue_gym.suites import PAPER_CONFIG as SUITE_PAPER


def test_a_misspelt_option_is_a_type_error_listing_the_valid_ones() -> None:
    with pytest.raises(TypeError, match="num_wokers") as e:
        rogue_gym.make_vec(2, num_wokers=1)
    assert "num_workers" in str(e.value) and "step_timeout" in str(e.value)


def test_the_facades_take_their_defaults_from_pool_settings() -> None:
    from rogue_gym.sb3 import RogueVecEnv

    # make_vec's first argument is the env count for the native game (make_vec(8)), or an id;
    # without it (make_vec() or make_vec(num_envs=...)) the native game, PoolSettings' count.
    assert inspect.signature(rogue_gym.make_vec).parameters["env"].default is None
    envs = rogue_gym.make_vec(num_workers=1)
    assert envs.num_envs == PoolSettings.num_envs
    envs.close()
    for fn in (rogue_gym.make_vec, rogue_gym.RogueVectorEnv.__init__, RogueVecEnv.__init__):
        params = inspect.signature(fn).parameters
        if fn is not rogue_gym.make_vec:
            assert params["num_envs"].default == PoolSettings.num_envs, fn
        assert params["config"].default == PoolSettings.config, fn
        # Every other pool option goes through PoolSettings, not a copied keyword list.
        assert not {f.name for f in dataclasses.fields(PoolSettings)} - {
            "num_envs",
            "config",
        } & set(params), fn


def test_checked_settings_resolve_defaults_and_name_bad_values() -> None:
    s = PoolSettings(num_envs=6, num_workers=None, seed=None).checked()
    assert s.num_workers is not None and 6 % s.num_workers == 0
    assert isinstance(s.seed, int) and s.worker_command
    with pytest.raises(ValueError, match="on_worker_failure"):
        PoolSettings(on_worker_failure="ignore").checked()
    with pytest.raises(ValueError, match="max_steps"):
        PoolSettings(max_steps=0).checked()
    with pytest.raises(ValueError, match="step_timeout"):
        PoolSettings(step_timeout=0).checked()


def test_autoreset_modes_are_read_by_name_or_value_in_any_case() -> None:
    from gymnasium.vector import AutoresetMode
    from rogue_gym.settings import parse_autoreset_mode

    for spelling in ("NEXT_STEP", "next-step", "NextStep", AutoresetMode.NEXT_STEP):
        assert parse_autoreset_mode(spelling) is AutoresetMode.NEXT_STEP
    assert parse_autoreset_mode("disabled") is AutoresetMode.DISABLED
    with pytest.raises(ValueError, match="NEXT_STEP, SAME_STEP"):
        parse_autoreset_mode("DISABLED", (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP))
    with pytest.raises(ValueError, match="autoreset_mode"):
        rogue_gym.PoolVectorEnv([lambda: None], autoreset_mode="sometimes")


def test_the_paper_config_is_the_engines() -> None:
    # The Python dict (original style) and the engine's GameConfig::paper() are the same game.
    normalised = _native.Game(json.dumps(rogue_gym.PAPER_CONFIG), 500, 50.0).config_json()
    assert json.loads(normalised) == json.loads(_native.PAPER_CONFIG_JSON)
    # The suites' copy is the same config without the training seed range.
    assert {**SUITE_PAPER, "seed_range": [0, 40]} == rogue_gym.PAPER_CONFIG


def test_constants_come_from_the_native_module() -> None:
    assert (
        rogue_gym.ACTIONS == _native.ACTION_KEYS and len(rogue_gym.ACTIONS) == _native.NUM_ACTIONS
    )
    assert {_native.SUMMARY_RESTARTED, _native.SUMMARY_FINAL} == {1, 2}


def test_obs_specs_are_parsed_by_the_engine() -> None:
    s = ObsSpec("onehot", np.float32, 3, False, True).validated()
    assert s == ObsSpec("symbol_onehot", "float32", 3, False, True)
    assert ObsSpec("status_vector", "uint8").validated().encoding == "status"
    with pytest.raises(ValueError, match="unknown observation encoding `pixels`"):
        ObsSpec("pixels", "uint8").validated()
    with pytest.raises(ValueError, match="dtype `float64`"):
        ObsSpec("gray", "float64").validated()
    with pytest.raises(ValueError, match="status must be a bit mask"):
        ObsSpec("gray", "uint8", 1 << 12).validated()
    with pytest.raises(ValueError, match="status must be a bit mask"):
        ObsSpec("gray", "uint8", -1).validated()


def test_start_timeout_is_checked_and_reaches_the_pool_through_every_class() -> None:
    """Every class takes ``start_timeout``: a start that cannot finish within it raises within
    ``step_timeout + start_timeout``, naming the setting."""
    import gymnasium as gym
    from rogue_gym import PoolVectorEnv, WorkerCrashedError
    from rogue_gym.sb3 import PoolVecEnv, RogueVecEnv

    with pytest.raises(ValueError, match="start_timeout must be a positive number"):
        PoolSettings(start_timeout=0).checked()
    with pytest.raises(ValueError, match="start_timeout must be a positive number"):
        PoolVectorEnv([lambda: gym.make("CartPole-v1")], start_timeout=-1.0)
    opts = {"num_workers": 1, "step_timeout": 0.3, "start_timeout": 0.002, "max_restarts": 10}
    makers = {
        "make_vec": lambda: rogue_gym.make_vec(2, **opts),
        "RogueVecEnv": lambda: RogueVecEnv(2, **opts),
        "PoolVectorEnv": lambda: PoolVectorEnv([lambda: gym.make("CartPole-v1")] * 2, **opts),
        "PoolVecEnv": lambda: PoolVecEnv([lambda: gym.make("CartPole-v1")] * 2, **opts),
    }
    for name, make in makers.items():
        with pytest.raises(WorkerCrashedError, match="start_timeout 2ms") as info:
            make()
        assert "restart budget exhausted" in str(info.value) or info.value.restarting, name
