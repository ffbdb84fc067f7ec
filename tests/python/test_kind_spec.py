"""A new env kind is one small class implementing :class:`rogue_gym.kinds.spec.Kind`: here the
pool's built-in deterministic test env (``"kind": "test"``, run by the workers in Rust) becomes
a gymnasium vector env with nothing but its spec, and the front does the rest (the call
lifecycle, resets, partial resets, the async API, refusing what the kind does not serve)."""

from __future__ import annotations

import sys
from typing import Any, Optional, Sequence

import numpy as np
import pytest
from gymnasium import spaces
from rogue_gym.front.vector_env import FrontVectorEnv
from rogue_gym.kinds.final_obs import add_final_obs
from rogue_gym.kinds.result import Result
from rogue_gym.kinds.spec import EnvIds, Kind, KindFacts
from rogue_gym.kinds.view import PoolView
from rogue_gym.protocol.ops import run_op
from rogue_gym.settings import PoolOptions

from conftest import pool_files

#: The test env's observation and actions (see ``pool/src/kinds/test_env.rs``).
OBS_SHAPE, NUM_ACTIONS, MAX_STEPS = (6,), 3, 5


class ToyKind:
    """The least a kind needs: facts, settings, codecs, seeds, infos, operations, render; it
    reads the pool through the view it is bound to."""

    def __init__(
        self, num_envs: int, obs_shape: tuple[int, ...] = OBS_SHAPE, num_workers: int = 2
    ) -> None:
        self.obs_shape, self.num_workers = obs_shape, num_workers
        self.facts = KindFacts(
            num_envs=num_envs,
            single_observation_space=spaces.Box(0, 255, obs_shape, np.uint8),
            single_action_space=spaces.Discrete(NUM_ACTIONS),
            metadata={"render_modes": []},
            render_mode=None,
            env_spec=None,
            worker_command=[sys.executable, "-m", "rogue_gym.worker"],
            who="the toy env",
            ops=frozenset({"call"}),
        )
        self._base = 0
        self.view: Optional[PoolView] = None

    def pool_settings(self) -> dict[str, Any]:
        env = {"kind": "test", "obs_shape": list(self.obs_shape), "num_actions": NUM_ACTIONS}
        return {
            **PoolOptions(num_workers=self.num_workers).pool_json(self.facts.num_envs),
            "env": {**env, "max_steps": MAX_STEPS},
            "seeds": self._schedule(),
        }

    def _schedule(self) -> dict[str, Any]:
        return {
            "base": self._base,
            "set": {"range": {"start": 0, "end": 1000}},
            "policy": "sequential",
        }

    def bind(self, view: PoolView) -> None:
        self.view = view

    def batch_views(self, rows: np.ndarray) -> np.ndarray:
        return rows.reshape((rows.shape[0], *self.obs_shape))

    def actions(self, actions: Any, env_ids: Optional[EnvIds]) -> np.ndarray:
        return np.asarray(actions, np.int64)

    def seeds(self, seed: Any, mask: Optional[np.ndarray]) -> Optional[dict[str, Any]]:
        if mask is not None:
            raise ValueError("the toy env's seeds are a schedule: no seeded partial resets")
        if seed is None:
            return None
        self._base = int(seed)
        return self._schedule()

    def infos(self, result: Result, only: Optional[np.ndarray]) -> dict[str, Any]:
        t = result.cols["info_int"][0].copy()
        infos = {"t": t, "_t": np.ones(result.rows, bool) if only is None else only}
        assert self.view is not None
        # SAME_STEP: the slot's final observations, as they are, with no info of their own.
        return add_final_obs(infos, self.view, result, self.batch_views, lambda e, o: (o, {}))

    def run_ops(
        self,
        op: str,
        name: str,
        arguments: Sequence[tuple[tuple[Any, ...], dict[str, Any]]],
        indices: Sequence[int],
    ) -> list[Any]:
        table = {"call": lambda name, env: {"max_steps": MAX_STEPS}[name]}
        return [run_op(table, self.facts.who, op, name, env) for env in indices]

    def render(self) -> Optional[tuple[Any, ...]]:
        return None


@pytest.fixture
def toy() -> Any:
    envs: list[FrontVectorEnv] = []

    def make(num_envs: int = 4, **kw: Any) -> FrontVectorEnv:
        kind: Kind = ToyKind(num_envs)
        env = FrontVectorEnv(kind, **kw)
        envs.append(env)
        return env

    yield make
    for env in envs:
        name = env.pool_name
        env.close()
        assert pool_files(name) == []


def test_a_kind_of_a_few_members_runs_through_every_call_of_the_front(toy) -> None:
    env = toy()
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(4, np.int64))
    obs, infos = env.reset(seed=3)
    assert obs.shape == (4, *OBS_SHAPE) and infos["t"].tolist() == [0, 0, 0, 0]
    ends = 0
    for _ in range(2 * MAX_STEPS + 1):
        obs, rew, term, trunc, infos = env.step(np.ones(4, np.int64))
        ends += int(trunc.sum() + term.sum())
    assert ends >= 4  # every env's episode ended once (the step limit), autoreset by the front
    mask = np.array([True, False, False, True])
    _, infos = env.reset(options={"reset_mask": mask})
    assert infos["_t"].tolist() == mask.tolist() and infos["t"][mask].tolist() == [0, 0]
    assert env.get_attr("max_steps") == (MAX_STEPS,) * 4
    with pytest.raises(NotImplementedError, match=r"the toy env does not serve .*'render'"):
        env.call_envs("render", "", [((), {})] * 4)


def test_the_toy_kind_is_deterministic_through_the_async_api_too(toy) -> None:
    sync, pooled = toy(), toy()
    want, _ = sync.reset(seed=9)
    pooled.async_reset(seed=9)
    obs, *_, infos = pooled.recv()
    order = np.argsort(infos["env_id"])
    assert np.array_equal(obs[order], want)
    for _ in range(MAX_STEPS + 2):
        a = np.array([0, 1, 2, 1], np.int64)
        want = sync.step(a)[0]
        pooled.send(a, np.arange(4))
        obs, *_, infos = pooled.recv()
        assert np.array_equal(obs[np.argsort(infos["env_id"])], want)


def test_same_step_final_observations_come_with_the_kinds_infos(toy) -> None:
    env = toy(autoreset_mode="SameStep")
    env.reset(seed=1)
    ended = np.zeros(4, bool)
    for _ in range(MAX_STEPS):
        obs, _, term, trunc, infos = env.step(np.ones(4, np.int64))
        ended = term | trunc
        if ended.any():
            break
    assert ended.any()
    assert infos["_final_obs"].tolist() == ended.tolist()
    for e in np.flatnonzero(ended):
        final = infos["final_obs"][e]
        assert final.shape == OBS_SHAPE and not np.shares_memory(final, obs)


def test_a_bound_kind_makes_no_reference_cycle_with_the_front() -> None:
    """The kind keeps its view, not the front: dropping the last reference to the vector env
    frees its core (and stops its workers) at once, with the cycle collector off."""
    import gc
    import weakref

    gc.disable()
    try:
        env = FrontVectorEnv(ToyKind(2))
        env.reset(seed=0)
        name, core = env.pool_name, weakref.ref(env._core)
        del env
        assert core() is None
        assert pool_files(name) == []
    finally:
        gc.enable()
