"""PettingZoo envs in the pool, one row per (env, agent): the rows equal a plain loop over the
same PettingZoo envs (observations, rewards, flags, which agents are there), whatever the
worker count; agents that die; envs that end as a whole in both autoreset modes; spaces that
differ are refused; the SB3 facade."""

from __future__ import annotations

from typing import Any, Callable

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode
from rogue_gym import PoolVectorEnv

pytest.importorskip("pettingzoo")
from pettingzoo.butterfly import knights_archers_zombies_v11, pistonball_v6
from pettingzoo.utils.env import ParallelEnv

mpe2 = pytest.importorskip("mpe2")
from mpe2 import simple_adversary_v3, simple_spread_v3  # noqa: E402

from conftest import pool_files  # noqa: E402


def spread() -> Any:
    return simple_spread_v3.parallel_env(max_cycles=12)


#: Knights-archers-zombies whose agents die early (line_death: touching a wall kills) and
#: whose episode ends at 60 cycles.
KAZ = {"line_death": True, "spawn_delay": 5, "max_cycles": 60}


def kaz() -> Any:
    return knights_archers_zombies_v11.parallel_env(**KAZ)


def kaz_aec() -> Any:
    return knights_archers_zombies_v11.env(**KAZ)


def pistonball() -> Any:
    return pistonball_v6.parallel_env(n_pistons=3, max_cycles=15)


ENVS = {"simple_spread": spread, "kaz": kaz, "pistonball": pistonball}


def plain_loop(
    env_fn: Callable[[], Any], n: int, seed: int, actions: list[np.ndarray]
) -> list[tuple[np.ndarray, ...]]:
    """What the rows must be, from the PettingZoo envs stepped one by one (NEXT_STEP): per
    call ``(obs, rewards, terminated, truncated, active)`` of every row."""
    envs = [env_fn() for _ in range(n)]
    agents = list(envs[0].possible_agents)
    a_n = len(agents)
    space = envs[0].observation_space(agents[0])
    obs = np.zeros((n * a_n, *space.shape), space.dtype)
    active = np.zeros(n * a_n, bool)
    out = []
    for e, env in enumerate(envs):
        o, _ = env.reset(seed=seed + e)
        for j, a in enumerate(agents):
            obs[e * a_n + j] = o.get(a, 0)
            active[e * a_n + j] = a in env.agents
    out.append((obs.copy(), None, None, None, active.copy()))
    ended = [False] * n
    for act in actions:
        rew = np.zeros(n * a_n)
        term = np.zeros(n * a_n, bool)
        trunc = np.zeros(n * a_n, bool)
        for e, env in enumerate(envs):
            rows = slice(e * a_n, (e + 1) * a_n)
            if ended[e]:
                o, _ = env.reset()
                obs[rows] = 0
                active[rows] = False
                for j, a in enumerate(agents):
                    if a in o:
                        obs[e * a_n + j] = o[a]
                    active[e * a_n + j] = a in env.agents
                ended[e] = False
                continue
            alive = list(env.agents)
            step = {a: act[e * a_n + agents.index(a)] for a in alive}
            o, r, te, tr, _ = env.step(step)
            obs[rows] = 0
            active[rows] = False
            for j, a in enumerate(agents):
                row = e * a_n + j
                if a in o:
                    obs[row] = o[a]
                if a in alive:
                    active[row] = True
                    rew[row], term[row], trunc[row] = (
                        r.get(a, 0),
                        te.get(a, False),
                        tr.get(a, False),
                    )
            ended[e] = not env.agents
        out.append((obs.copy(), rew, term, trunc, active.copy()))
    for env in envs:
        env.close()
    return out


def _actions(env: Any, steps: int, seed: int) -> list[np.ndarray]:
    env.action_space.seed(seed)
    return [env.action_space.sample() for _ in range(steps)]


@pytest.fixture
def pools() -> Any:
    made: list[PoolVectorEnv] = []

    def make(env_fn: Callable[[], Any], n: int, **kw: Any) -> PoolVectorEnv:
        env = PoolVectorEnv.from_pettingzoo(env_fn, n, **kw)
        made.append(env)
        return env

    yield make
    for env in made:
        name = env.pool_name
        env.close()
        assert pool_files(name) == []


@pytest.mark.parametrize("name", list(ENVS))
def test_rows_equal_a_plain_loop_over_the_pettingzoo_envs(name, pools) -> None:
    env_fn = ENVS[name]
    n = 2 if name == "pistonball" else 3
    env = pools(env_fn, n, num_workers=2)
    steps = {"simple_spread": 30, "kaz": 130, "pistonball": 20}[name]
    actions = _actions(env, steps, seed=1)
    want = plain_loop(env_fn, n, 7, actions)
    obs, infos = env.reset(seed=7)
    assert np.array_equal(obs, want[0][0]) and np.array_equal(infos["active"], want[0][4])
    ends = deaths = 0
    for t, act in enumerate(actions, start=1):
        obs, rew, term, trunc, infos = env.step(act)
        w_obs, w_rew, w_term, w_trunc, w_active = want[t]
        assert np.array_equal(obs, w_obs), (name, t)
        assert np.array_equal(rew, w_rew) and rew.dtype == np.float64, (name, t)
        assert np.array_equal(term, w_term) and np.array_equal(trunc, w_trunc), (name, t)
        assert np.array_equal(infos["active"], w_active), (name, t)
        ends += int((term | trunc).sum())
        deaths += int((~infos["active"]).sum())
    assert ends > 0, "the run crosses episode ends"
    stats = env.stats()  # the workers count the rows they step
    assert (
        len(stats.workers) == 2 and sum(w.env_steps for w in stats.workers) >= steps * env.num_envs
    )
    if name == "kaz":
        assert deaths > 0, "agents died and their rows went inactive"


def test_the_trajectory_does_not_depend_on_the_worker_count(pools) -> None:
    one, three = pools(kaz, 3, num_workers=1), pools(kaz, 3, num_workers=3)
    assert [len(three.envs_of_worker(k)) for k in range(3)] == [4, 4, 4]  # whole envs
    a, _ = one.reset(seed=3)
    b, _ = three.reset(seed=3)
    assert np.array_equal(a, b)
    for act in _actions(one, 80, seed=2):
        ra, rb = one.step(act), three.step(act)
        for x, y in zip(ra[:4], rb[:4]):
            assert np.array_equal(x, y)
        assert np.array_equal(ra[4]["active"], rb[4]["active"])


def test_same_step_ends_an_env_as_a_whole_with_each_rows_final_observation(pools) -> None:
    """SAME_STEP: a row whose agent is done at a step has its last observation in
    ``final_obs`` (its row: zeros while the env goes on); when an env's last agent is done the
    env resets at once, with the first observations of its next episode."""
    env = pools(kaz, 2, num_workers=2, autoreset_mode=AutoresetMode.SAME_STEP)
    actions = _actions(env, 70, seed=5)
    want = plain_loop(kaz, 2, 4, actions)  # NEXT_STEP: an ended env resets a step later
    env.reset(seed=4)
    finals = 0
    for t, act in enumerate(actions, start=1):
        obs, rew, term, trunc, infos = env.step(act)
        w_obs, w_rew, w_term, w_trunc, w_active = want[t]
        assert np.array_equal(term, w_term) and np.array_equal(trunc, w_trunc), t
        assert np.array_equal(rew, w_rew), t
        done = term | trunc
        for row in np.flatnonzero(done):
            assert np.array_equal(infos["final_obs"][row], w_obs[row]), (t, row)
            finals += 1
        ended = [
            e
            for e in range(2)
            if done[4 * e : 4 * e + 4].any()
            and np.array_equal(done[4 * e : 4 * e + 4], w_active[4 * e : 4 * e + 4])
        ]
        for e in range(2):
            rows = slice(4 * e, 4 * e + 4)
            if e in ended:  # reset at once: the plain loop's next step
                assert np.array_equal(obs[rows], want[t + 1][0][rows]), t
                assert np.array_equal(infos["active"][rows], want[t + 1][4][rows]), t
            else:
                going = w_obs[rows].copy()
                going[done[rows]] = 0
                assert np.array_equal(obs[rows], going), t
        if ended:
            break
    else:
        pytest.fail("no env ended within its max_cycles")
    assert finals > 0


def test_agents_with_different_spaces_are_refused_with_how_to_pad_them() -> None:
    with pytest.raises(ValueError, match="pad_observations_v0"):
        PoolVectorEnv.from_pettingzoo(lambda: simple_adversary_v3.parallel_env(), 2)


def test_the_sb3_facade_shares_parameters_over_the_rows() -> None:
    pytest.importorskip("stable_baselines3")
    from rogue_gym.sb3 import PoolVecEnv

    venv = PoolVecEnv.from_pettingzoo(spread, 2, num_workers=2)
    try:
        assert venv.num_envs == 6
        obs = venv.reset()
        assert obs.shape == (6, 18)
        dones_seen = 0
        for _ in range(13):
            obs, rewards, dones, infos = venv.step(np.zeros(6, np.int64))
            assert len(infos) == 6
            dones_seen += int(dones.sum())
            for i, info in enumerate(infos):  # an ended row's info is its last step's (SB3)
                assert ("terminal_observation" in info) if dones[i] else info["active"]
        assert dones_seen == 6  # every row's episode truncated at max_cycles once
    finally:
        venv.close()


class OneEnvView(ParallelEnv):
    """One env of a pool seen as a PettingZoo ``ParallelEnv``: its active rows are the agents
    (for PettingZoo's own checks)."""

    def __init__(self, env_fn: Callable[[], Any]) -> None:
        probe = env_fn()
        self.possible_agents = list(probe.possible_agents)
        self.metadata = probe.metadata
        self._obs_space = probe.observation_space(self.possible_agents[0])
        self._act_space = probe.action_space(self.possible_agents[0])
        probe.close()
        self.pool = PoolVectorEnv.from_pettingzoo(env_fn, 1, num_workers=1)
        self.agents: list[Any] = []

    def observation_space(self, agent: Any) -> Any:
        return self._obs_space

    def action_space(self, agent: Any) -> Any:
        return self._act_space

    def reset(self, seed: Any = None, options: Any = None) -> Any:
        obs, infos = self.pool.reset(seed=seed, options=options)
        self.agents = [a for j, a in enumerate(self.possible_agents) if infos["active"][j]]
        return {a: obs[self.possible_agents.index(a)] for a in self.agents}, {
            a: {} for a in self.agents
        }

    def step(self, actions: dict[Any, Any]) -> Any:
        rows = np.zeros(self.pool.action_space.shape, self.pool.action_space.dtype)
        for a, act in actions.items():
            rows[self.possible_agents.index(a)] = act
        obs, rew, term, trunc, _ = self.pool.step(rows)
        acted, idx = self.agents, self.possible_agents.index
        out = (
            {a: obs[idx(a)] for a in acted},
            {a: float(rew[idx(a)]) for a in acted},
            {a: bool(term[idx(a)]) for a in acted},
            {a: bool(trunc[idx(a)]) for a in acted},
            {a: {} for a in acted},
        )
        self.agents = [a for a in acted if not (term[idx(a)] or trunc[idx(a)])]
        return out

    def close(self) -> None:
        self.pool.close()


@pytest.mark.parametrize("name", list(ENVS))
def test_pettingzoos_own_api_and_seed_tests_pass_on_one_env_of_the_pool(name) -> None:
    from pettingzoo.test import parallel_api_test, parallel_seed_test

    cycles = {"simple_spread": 30, "kaz": 80, "pistonball": 10}[name]
    view = OneEnvView(ENVS[name])
    try:
        parallel_api_test(view, num_cycles=cycles)
    finally:
        view.close()
    views: list[OneEnvView] = []

    def make() -> OneEnvView:
        views.append(OneEnvView(ENVS[name]))
        return views[-1]

    try:
        parallel_seed_test(make, num_cycles=cycles)
    finally:
        for v in views:
            v.close()


def _spread_short() -> Any:
    return simple_spread_v3.parallel_env(N=2, max_cycles=25, local_ratio=0.5)


def _mean_return(model: Any, venv: Any, episodes: int) -> float:
    """Mean return per agent-episode of ``model`` (``None``: uniform random actions)."""
    rng = np.random.default_rng(0)
    venv.seed(123)
    obs = venv.reset()
    returns: list[float] = []
    while len(returns) < episodes:
        if model is None:
            actions = rng.integers(0, venv.action_space.n, venv.num_envs)
        else:
            actions, _ = model.predict(obs, deterministic=True)
        obs, _, dones, infos = venv.step(actions)
        returns.extend(float(i["episode"]["r"]) for i, d in zip(infos, dones) if d)
    return float(np.mean(returns))


def test_sb3_ppo_with_shared_parameters_learns_simple_spread() -> None:
    """A short PPO run over the rows (2 agents per env, one shared policy) beats the random
    policy's return per agent-episode on the same seeds by a margin."""
    pytest.importorskip("stable_baselines3")
    import torch
    from rogue_gym.sb3 import PoolVecEnv
    from stable_baselines3 import PPO

    torch.set_num_threads(1)
    venv = PoolVecEnv.from_pettingzoo(_spread_short, 8, num_workers=2)
    try:
        random_return = _mean_return(None, venv, 64)
        model = PPO(
            "MlpPolicy",
            venv,
            n_steps=64,
            batch_size=256,
            n_epochs=4,
            seed=0,
            learning_rate=1e-3,
            verbose=0,
        )
        model.learn(total_timesteps=100_000)  # about 15 s on 2 cores
        trained = _mean_return(model, venv, 64)
    finally:
        venv.close()
    # Measured: random -21.6, trained -15.6 (28% better); the bar is 15%.
    assert trained > random_return + 0.15 * abs(random_return), (trained, random_return)


def test_the_async_api_serves_an_envs_rows_together(pools) -> None:
    """``recv`` hands over whole envs: the rows of one env come in one batch."""
    env = pools(kaz, 4, num_workers=2, batch_size=8)
    env.async_reset(seed=1)
    for _ in range(30):
        obs, rew, term, trunc, infos = env.recv()
        ids = np.sort(infos["env_id"])
        assert len(ids) == 8 and obs.shape[0] == 8
        assert set(np.unique(ids // 4)) == set((ids // 4).tolist())
        assert all((ids // 4 == e).sum() == 4 for e in np.unique(ids // 4))
        env.send(np.zeros(8, np.int64), infos["env_id"])


def test_a_killed_worker_costs_its_envs_one_truncated_episode(pools) -> None:
    import os
    import signal

    env = pools(spread, 2, num_workers=2)
    env.reset(seed=0)
    victim = env.worker_pids[1]
    os.kill(victim, signal.SIGKILL)
    _, _, _, trunc, infos = env.step(env.action_space.sample())
    assert infos["worker_restarted"].tolist() == [False] * 3 + [True] * 3
    assert trunc[3:].all() and not trunc[:3].any()
    assert env.worker_pids[1] != victim
    for _ in range(3):  # the rebuilt env steps on, all its agents there
        *_, infos = env.step(env.action_space.sample())
        assert infos["active"].all()


def test_an_aec_env_is_hosted_through_aec_to_parallel(pools) -> None:
    aec = pools(kaz_aec, 2)
    par = pools(kaz, 2)
    a, _ = aec.reset(seed=2)
    b, _ = par.reset(seed=2)
    assert np.array_equal(a, b)
    for act in _actions(par, 40, seed=3):
        ra, rb = aec.step(act), par.step(act)
        assert all(np.array_equal(x, y) for x, y in zip(ra[:4], rb[:4]))


def test_tune_times_pettingzoo_envs_as_rows() -> None:
    import io

    import rogue_gym

    out = io.StringIO()
    result = rogue_gym.tune(spread, 2, seconds=0.05, rounds=1, cpus=1, out=out)
    assert result.kind == "pettingzoo"
    modes = {t.candidate.mode for t in result.timings}
    assert modes == {"pool", "sync"} and all(t.median > 0 for t in result.timings)
    advice = result.advice()
    assert "from_pettingzoo(env_fn, 2," in advice or "AgentRows" in advice
    assert advice in out.getvalue()


def test_seeds_follow_supersuits_rule() -> None:
    """``reset(seed=s)`` seeds env ``e`` with ``s + e``, as SuperSuit's ``concat_vec_envs``:
    the first observations equal its, row for row, whatever the worker count."""
    ss = pytest.importorskip("supersuit")
    theirs = ss.concat_vec_envs_v1(
        ss.pettingzoo_env_to_vec_env_v1(spread()), 3, num_cpus=0, base_class="gymnasium"
    )
    try:
        want, _ = theirs.reset(seed=5)
    finally:
        theirs.close()
    for workers in (1, 3):
        env = PoolVectorEnv.from_pettingzoo(spread, 3, num_workers=workers)
        try:
            got, _ = env.reset(seed=5)
        finally:
            env.close()
        np.testing.assert_array_equal(got, want, err_msg=f"{workers} workers")
