"""Pools under Ray, on a local two-CPU cluster: RLlib trains through them, the actor-backed
vector env plays what one local pool plays, a killed actor costs one flagged episode, and
nothing is left in /dev/shm or the temp dirs after ``ray.shutdown()``.

Run with the Ray environment (``bash scripts/setup-ray.sh``; ``scripts/test.sh`` does it):
``.venv-ray/bin/python -m pytest tests/ray``. Kept out of ``tests/python`` so the light path
never imports Ray.
"""

from __future__ import annotations

import os
import shutil
import signal
import tempfile
import time
from collections.abc import Iterator

import gymnasium as gym
import numpy as np
import pytest
import rogue_gym

ray = pytest.importorskip("ray")

from rogue_gym.ray import RayVectorEnv, configure_rllib  # noqa: E402

pytestmark = pytest.mark.timeout(300)

#: Short episodes, so that episodes finish within a couple of RLlib iterations.
POOL = {"obs": "symbol_index", "num_workers": 1, "max_steps": 40}


def _ours() -> set[str]:
    """The pool files in /dev/shm and in the pools' runtime directory."""
    files = {f"/dev/shm/{f}" for f in os.listdir("/dev/shm") if f.startswith("rg")}
    base = rogue_gym._native.default_runtime_dir()
    if os.path.isdir(base):
        files |= {f"{base}/{f}" for f in os.listdir(base)}
    return files


@pytest.fixture(scope="module")
def cluster() -> Iterator[None]:
    """A local Ray cluster with two CPUs; after shutdown, no pool file and no Ray temp dir."""
    before = _ours()
    temp = tempfile.mkdtemp(prefix="rgray")  # short: Ray's socket paths must fit 107 bytes
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, _temp_dir=temp)
    try:
        yield
    finally:
        ray.shutdown()
        deadline = time.monotonic() + 30
        while _ours() - before and time.monotonic() < deadline:
            time.sleep(0.2)
        shutil.rmtree(temp, ignore_errors=True)
    assert not (_ours() - before), f"left behind after ray.shutdown(): {_ours() - before}"


def _same(a: tuple, b: tuple) -> None:
    for x, y in zip(a[:4], b[:4]):
        np.testing.assert_array_equal(x, y)


def test_rllib_ppo_trains_through_pools(cluster: None) -> None:
    from ray.rllib.algorithms.ppo import PPOConfig

    config = (
        PPOConfig()
        .training(train_batch_size_per_learner=200, minibatch_size=50, num_epochs=1)
        .debugging(seed=0)
    )
    config = configure_rllib(config, num_env_runners=1, num_envs_per_env_runner=4, **POOL)
    assert config.num_cpus_per_env_runner == 2 and config.env_config["copy"] is True
    assert config.rl_module_spec.module_class.__name__ == "RogueRLModule"
    algo = config.build_algo()
    try:
        for _ in range(2):
            result = algo.train()
        runners = result["env_runners"]
        assert runners["num_env_steps_sampled_lifetime"] >= 400
        assert runners["num_episodes_lifetime"] > 0
        assert np.isfinite(runners["episode_return_mean"])
    finally:
        algo.stop()


def test_rllib_trains_a_hosted_gymnasium_env_through_pools(cluster: None) -> None:
    from ray.rllib.algorithms.ppo import PPOConfig

    config = PPOConfig().training(train_batch_size_per_learner=200, minibatch_size=50, num_epochs=1)
    config = configure_rllib(
        config, "CartPole-v1", num_env_runners=1, num_envs_per_env_runner=4, num_workers=1
    )
    assert config.rl_module_spec.module_class.__name__ == "DefaultPPOTorchRLModule"
    algo = config.build_algo()
    try:
        runners = algo.train()["env_runners"]
        assert runners["num_env_steps_sampled_lifetime"] >= 200
        assert runners["num_episodes_lifetime"] > 0  # CartPole's random episodes are short
    finally:
        algo.stop()


def test_two_env_runners_share_the_node_and_train(cluster: None) -> None:
    """Two EnvRunners on the 2-CPU node, a pool each: the pools see each other in their user's
    ledger (so neither polls long), and the training is what one runner's would be: it runs,
    sampling from both."""
    from ray.rllib.algorithms.ppo import PPOConfig

    config = PPOConfig().training(train_batch_size_per_learner=200, minibatch_size=50, num_epochs=1)
    config = configure_rllib(
        config,
        "CartPole-v1",
        num_env_runners=2,
        num_envs_per_env_runner=4,
        num_workers=1,
        num_cpus_per_env_runner=1,
    )
    algo = config.build_algo()
    try:
        runners = algo.train()["env_runners"]
        assert runners["num_env_steps_sampled_lifetime"] >= 200
        assert runners["num_episodes_lifetime"] > 0
        seen = algo.env_runner_group.foreach_env_runner(
            lambda r: (r.env.unwrapped.stats().machine, r.env.unwrapped.pool_name),
            local_env_runner=False,
        )
    finally:
        algo.stop()
    assert len(seen) == 2
    names = {name for _, name in seen}
    for machine, name in seen:
        assert {o["pool"] for o in machine["others"]} == names - {name}, machine


@pytest.mark.parametrize("num_actors", [1, 2])
def test_actor_envs_play_what_one_local_pool_plays(cluster: None, num_actors: int) -> None:
    envs = RayVectorEnv("RogueGym-v0", 7, num_actors=num_actors, seed=5, **POOL)
    local = rogue_gym.make_vec(7, seed=5, **POOL)
    try:
        (o1, i1), (o2, i2) = envs.reset(seed=11), local.reset(seed=11)
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(i1["seed"], i2["seed"])
        rng = np.random.default_rng(0)
        ends = 0
        for _ in range(120):
            a = rng.integers(0, 11, 7)
            x, y = envs.step(a), local.step(a)
            _same(x, y)
            ends += int(x[2].sum() + x[3].sum())
            np.testing.assert_array_equal(x[4]["seed"], y[4]["seed"])
        assert ends >= 7  # every env went through an episode end and an autoreset
    finally:
        envs.close()
        local.close()


def test_hosted_envs_under_actors_are_seeded_as_one_pool(cluster: None) -> None:
    envs = RayVectorEnv("CartPole-v1", 5, num_actors=2, num_workers=1)
    local = gym.vector.SyncVectorEnv([lambda: gym.make("CartPole-v1")] * 5)
    try:
        np.testing.assert_array_equal(envs.reset(seed=3)[0], local.reset(seed=3)[0])
        rng = np.random.default_rng(1)
        for _ in range(60):
            a = rng.integers(0, 2, 5)
            _same(envs.step(a), local.step(a))
    finally:
        envs.close()
        local.close()


def test_send_recv_fans_out_by_actor_block(cluster: None) -> None:
    envs = RayVectorEnv("RogueGym-v0", 6, num_actors=2, seed=1, **POOL)
    try:
        envs.reset()
        envs.send(np.zeros(6, np.int64))
        seen = []
        while len(seen) < 6:
            obs, rewards, *_, infos = envs.recv()
            assert obs.shape[0] == len(infos["env_id"]) == len(rewards)
            seen += infos["env_id"].tolist()
            envs.send(np.zeros(len(infos["env_id"]), np.int64))  # answer that block
        assert sorted(seen) == list(range(6))
        with pytest.raises(ValueError, match="whole actor blocks"):
            envs.send(np.zeros(2, np.int64), env_id=[1, 2])
    finally:
        envs.close()


def test_a_killed_actor_is_replaced_and_its_envs_report_truncated(cluster: None) -> None:
    envs = RayVectorEnv("RogueGym-v0", 6, num_actors=2, seed=2, **POOL)
    try:
        envs.reset()
        pids = envs.actor_pids()
        os.kill(pids[1], signal.SIGKILL)
        obs, rewards, terminated, truncated, infos = envs.step(np.zeros(6, np.int64))
        assert truncated[3:].all() and not truncated[:3].any()
        np.testing.assert_array_equal(infos["actor_restarted"], [0, 0, 0, 1, 1, 1])
        assert (rewards[3:] == 0).all() and obs.shape[0] == 6
        assert envs.actor_restarts == 1 and envs.actor_pids()[1] != pids[1]
        for _ in range(5):  # the run goes on
            *_, truncated, infos = envs.step(np.ones(6, np.int64))
            assert "actor_restarted" not in infos
    finally:
        envs.close()


def test_actors_that_cannot_be_placed_fail_with_the_resources_named(cluster: None) -> None:
    with pytest.raises(RuntimeError, match="did not start"):
        RayVectorEnv("RogueGym-v0", 4, num_actors=2, step_timeout=5, actor_options={"num_cpus": 2})


def test_configure_rllib_routes_the_seed_to_rllib() -> None:
    from ray.rllib.algorithms.ppo import PPOConfig

    with pytest.raises(TypeError, match="debugging"):
        configure_rllib(PPOConfig(), seed=3)
    with pytest.raises(ValueError, match="copy"):
        configure_rllib(PPOConfig(), copy=False)


@pytest.mark.parametrize("obs", ["symbol_index", "symbol_onehot"])
def test_the_rl_module_reads_the_pools_uint8_observations(obs: str) -> None:
    import torch
    from ray.rllib.core.columns import Columns
    from rogue_gym.ray import RogueRLModule

    envs = rogue_gym.make_vec(3, num_workers=1, obs=obs, seed=0)
    try:
        batch, _ = envs.reset()
        module = RogueRLModule(
            observation_space=envs.single_observation_space,
            action_space=envs.single_action_space,
            model_config={"variant": "small"},
        )
        x = {Columns.OBS: torch.from_numpy(np.array(batch))}
        assert x[Columns.OBS].dtype == torch.uint8
        out = module.forward_train(x)
        assert out[Columns.ACTION_DIST_INPUTS].shape == (3, len(rogue_gym.ACTIONS))
        assert module.compute_values(x, out[Columns.EMBEDDINGS]).shape == (3,)
    finally:
        envs.close()
