"""Every public constructor takes its arguments as keywords (``make_vec(num_envs=8,
config="paper")`` once raised "got num_envs twice")."""

from __future__ import annotations

from typing import Any, Callable

import gymnasium as gym
import pytest
import rogue_gym
import rogue_gym.envpool as envpool
from rogue_gym import PoolVectorEnv, RogueVectorEnv

PAPER = rogue_gym.PAPER_CONFIG


def _cartpole() -> gym.Env:
    return gym.make("CartPole-v1")


def _sb3(name: str) -> Callable[..., Any]:
    pytest.importorskip("stable_baselines3")
    from rogue_gym import sb3

    return getattr(sb3, name)


BUILDS: dict[str, Callable[[], Any]] = {
    "make_vec(num_envs=, config=)": lambda: rogue_gym.make_vec(num_envs=3, config=PAPER),
    "make_vec(env=, num_envs=)": lambda: rogue_gym.make_vec(env="CartPole-v1", num_envs=3),
    "make_vec(env=callable, num_envs=)": lambda: rogue_gym.make_vec(env=_cartpole, num_envs=3),
    "RogueVectorEnv(num_envs=, config=)": lambda: RogueVectorEnv(num_envs=3, config=PAPER),
    "PoolVectorEnv(env_fns=)": lambda: PoolVectorEnv(env_fns=[_cartpole] * 3),
    "PoolVectorEnv.from_vector_env(vector_env_fn=, num_envs=)": lambda: (
        PoolVectorEnv.from_vector_env(
            vector_env_fn=lambda n: gym.make_vec("CartPole-v1", n, vectorization_mode="sync"),
            num_envs=3,
        )
    ),
    "gymnasium.make_vec(id, num_envs=)": lambda: gym.make_vec(
        rogue_gym.ENV_ID, num_envs=3, config=PAPER
    ),
    "envpool.make(task_id=, env_type=, num_envs=)": lambda: envpool.make(
        task_id="CartPole-v1", env_type="gymnasium", num_envs=3
    ),
    "sb3.RogueVecEnv(num_envs=, config=)": lambda: _sb3("RogueVecEnv")(num_envs=3, config=PAPER),
    "sb3.PoolVecEnv(env_fns=)": lambda: _sb3("PoolVecEnv")(env_fns=[_cartpole] * 3),
    "sb3.PoolVecEnv.from_vector_env(vector_env_fn=, num_envs=)": lambda: _sb3(
        "PoolVecEnv"
    ).from_vector_env(
        vector_env_fn=lambda n: gym.make_vec(
            "CartPole-v1",
            n,
            vectorization_mode="sync",
            vector_kwargs={"autoreset_mode": "SameStep"},
        ),
        num_envs=3,
    ),
}


@pytest.mark.parametrize("how", list(BUILDS))
def test_each_public_constructor_takes_keywords(how: str) -> None:
    envs = BUILDS[how]()
    try:
        assert envs.num_envs == 3
        envs.reset()
    finally:
        envs.close()


def test_the_number_of_envs_given_twice_says_so() -> None:
    with pytest.raises(TypeError, match="given twice"):
        rogue_gym.make_vec(4, num_envs=4)
