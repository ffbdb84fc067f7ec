"""Real training libraries over both env kinds: torchrl's ``GymWrapper`` and skrl's gymnasium
wrapper drive the pool as they drive gymnasium's own vector envs. Each test is skipped, with the
reason, where its library does not import."""

from __future__ import annotations

import warnings
from typing import Any, Callable, Iterator

import gymnasium as gym
import numpy as np
import pytest
import rogue_gym

from conftest import PAPER

NUM_ENVS, MAX_STEPS, STEPS = 4, 5, 12


@pytest.fixture
def pools() -> Iterator[Callable[..., Any]]:
    """``pools(kind, autoreset_mode)``: a 4-env pool of the native game (episodes of 5
    steps) or of hosted CartPole, closed at teardown."""
    made: list[Any] = []

    def factory(kind: str, autoreset_mode: str = "NEXT_STEP") -> Any:
        if kind == "native":
            env = rogue_gym.make_vec(
                NUM_ENVS,
                config=PAPER,
                num_workers=2,
                seed=0,
                max_steps=MAX_STEPS,
                obs="symbol_index",
                autoreset_mode=autoreset_mode,
            )
        else:
            env = rogue_gym.make_vec(
                "CartPole-v1", NUM_ENVS, num_workers=2, autoreset_mode=autoreset_mode
            )
        made.append(env)
        return env

    yield factory
    for env in made:
        env.close()


def _actions(n: int) -> np.ndarray:
    return np.random.default_rng(7).integers(0, 2, size=(STEPS, n))


def _direct(env: Any, actions: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Rewards and dones of ``actions`` stepped on ``env`` directly (SAME_STEP)."""
    env.reset(seed=seed)
    rewards, dones = [], []
    for a in actions:
        _, r, term, trunc, _ = env.step(a)
        rewards.append(r)
        dones.append(term | trunc)
    return np.array(rewards), np.array(dones)


@pytest.mark.parametrize("kind", ["native", "hosted"])
def test_torchrl_gym_wrapper_steps_the_pool_as_the_pool_steps(kind, pools) -> None:
    """torchrl's GymWrapper (SAME_STEP, which it runs with) gives the rewards and dones of the
    same actions stepped directly, and takes every info as a tensor (int64 seeds)."""
    pytest.importorskip("torchrl", reason="torchrl is not installed")
    import torch
    from torchrl.envs import GymWrapper

    actions = _actions(NUM_ENVS)
    want_r, want_d = _direct(pools(kind, "SAME_STEP"), actions, seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = GymWrapper(pools(kind, "SAME_STEP"))
    env.set_seed(3)
    step = iter(range(STEPS))

    def policy(td: Any) -> Any:
        a = torch.as_tensor(actions[next(step)])
        return td.set("action", torch.nn.functional.one_hot(a, env.action_spec.shape[-1]))

    out = env.rollout(STEPS, policy, break_when_any_done=False, auto_reset=True)
    got_r = out["next", "reward"].squeeze(-1).T.numpy()
    got_d = out["next", "done"].squeeze(-1).T.numpy()
    assert np.allclose(got_r, want_r) and np.array_equal(got_d, want_d)
    if kind == "native":  # the game's infos reach the tensordict, the seed among them
        assert out["next", "seed"].dtype == torch.int64
        assert int(want_d.sum()) == NUM_ENVS * (STEPS // MAX_STEPS)


def test_torchrl_runs_the_native_game_without_autoreset(pools) -> None:
    """DISABLED: torchrl resets the ended envs itself, through ``reset_mask``."""
    pytest.importorskip("torchrl", reason="torchrl is not installed")
    from torchrl.envs import GymWrapper

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = GymWrapper(pools("native", "DISABLED"))
    out = env.rollout(STEPS, break_when_any_done=False)
    assert out["next", "done"].sum().item() == NUM_ENVS * (STEPS // MAX_STEPS)


@pytest.mark.parametrize("kind", ["native", "hosted"])
def test_skrl_gymnasium_wrapper_steps_the_pool(kind, pools) -> None:
    """skrl's wrapper steps the pool: the native game gives what the same actions give
    stepped directly (both pools seeded alike at construction); CartPole pays 1 a step."""
    pytest.importorskip("skrl", reason="skrl is not installed")
    import torch
    from skrl.envs.wrappers.torch import wrap_env

    actions = _actions(NUM_ENVS)
    env = wrap_env(pools(kind, "SAME_STEP"), wrapper="gymnasium")
    assert env.num_envs == NUM_ENVS and isinstance(env.observation_space, gym.spaces.Space)
    obs, _ = env.reset()
    assert obs.shape[0] == NUM_ENVS
    rewards, dones = [], []
    for a in actions:
        _, r, term, trunc, _ = env.step(torch.as_tensor(a).reshape(-1, 1))
        rewards.append(r.squeeze(-1).numpy())
        dones.append((term | trunc).squeeze(-1).numpy())
    if kind == "hosted":
        assert (np.array(rewards) == 1).all()
        return
    direct = pools(kind, "SAME_STEP")
    direct.reset()
    want = [direct.step(a) for a in actions]
    assert np.allclose(np.array(rewards), [w[1] for w in want])
    assert np.array_equal(np.array(dones), [w[2] | w[3] for w in want])
