"""The generalization evaluator: statistics, policy loading, output, and runs through the pool."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from rogue_gym import evaluate as ev
from rogue_gym.scoring import episodes
from rogue_gym.suites import get_suite

# ------------------------------------------------------------------------------ bootstrap CI


def test_bootstrap_constant_values_give_zero_width() -> None:
    mean, lo, hi = ev.bootstrap_ci([7.0] * 50)
    assert mean == lo == hi == 7.0


def test_bootstrap_single_value() -> None:
    assert ev.bootstrap_ci([3.5]) == (3.5, 3.5, 3.5)


def test_bootstrap_empty_raises() -> None:
    with pytest.raises(ValueError):
        ev.bootstrap_ci([])


def test_bootstrap_contains_mean_and_is_reproducible() -> None:
    x = np.random.default_rng(1).exponential(20.0, size=200)
    mean, lo, hi = ev.bootstrap_ci(x)
    assert mean == pytest.approx(x.mean())
    assert lo < mean < hi
    assert ev.bootstrap_ci(x) == (mean, lo, hi)  # fixed RNG seed
    assert ev.bootstrap_ci(x, seed=1) != (mean, lo, hi)


def test_bootstrap_more_seeds_narrower_and_roughly_normal() -> None:
    rng = np.random.default_rng(2)
    small = rng.normal(10.0, 5.0, size=40)
    large = rng.normal(10.0, 5.0, size=1000)
    _, lo_s, hi_s = ev.bootstrap_ci(small)
    _, lo_l, hi_l = ev.bootstrap_ci(large)
    assert hi_l - lo_l < hi_s - lo_s
    # 95% CI of a mean ~ +-1.96 sigma/sqrt(n)
    expected = 2 * 1.96 * large.std(ddof=1) / np.sqrt(large.size)
    assert hi_l - lo_l == pytest.approx(expected, rel=0.15)


def test_bootstrap_higher_confidence_is_wider() -> None:
    x = np.arange(30, dtype=float)
    _, lo90, hi90 = ev.bootstrap_ci(x, confidence=0.90)
    _, lo99, hi99 = ev.bootstrap_ci(x, confidence=0.99)
    assert lo99 < lo90 and hi99 > hi90


def test_agent_result_is_across_seeds_not_episodes() -> None:
    # Seeds differ, episodes of one seed are identical: the CI must reflect the 3 seeds.
    returns = np.array([[0.0] * 10, [10.0] * 10, [20.0] * 10])
    a = ev.AgentResult.from_returns("x", returns, 0.95, 0)
    per_seed = ev.bootstrap_ci([0.0, 10.0, 20.0])
    assert (a.mean, a.ci_low, a.ci_high) == per_seed
    assert a.seed_std == pytest.approx(10.0)


# ------------------------------------------------------------------------------ policies


def test_random_policy_is_seeded() -> None:
    obs = np.zeros((8, 3), np.uint8)
    a = ev.RandomPolicy(seed=5)
    b = ev.RandomPolicy(seed=5)
    xs = [a(obs) for _ in range(3)]
    assert all(np.array_equal(x, b(obs)) for x in xs)
    assert xs[0].shape == (8,) and xs[0].dtype == np.int64
    assert min(x.min() for x in xs) >= 0 and max(x.max() for x in xs) < ev.NUM_ACTIONS
    a.seed(5)
    assert np.array_equal(a(obs), xs[0])


def test_load_policy_specs(tmp_path: Path) -> None:
    assert isinstance(ev.load_policy("random"), ev.RandomPolicy)
    assert isinstance(ev.load_policy("rogue_gym.evaluate:RandomPolicy"), ev.RandomPolicy)
    f = tmp_path / "mypol.py"
    f.write_text("import numpy as np\ndef act(obs):\n    return np.full(len(obs), 3)\n")
    pol = ev.load_policy(f"{f}:act")
    assert list(pol(np.zeros((2, 1)))) == [3, 3]
    with pytest.raises(ValueError):
        ev.load_policy("not-a-spec")


# ------------------------------------------------------------------------------ output


def _fake_result() -> dict:
    suite = get_suite("paper-10")
    returns = np.array([[1.0, 3.0], [50.0, 52.0]])
    agents = [ev.AgentResult.from_returns("pol", returns, 0.95, 0)]
    agents.append(ev.AgentResult.from_returns("random", returns / 2, 0.95, 0))
    return {
        "suite": suite.canonical(),
        "settings": {"seeds": [1000, 1001]},
        "agents": [a.to_json() for a in agents],
        "manifest": [{"seed": 1000, "rooms": 3}, {"seed": 1001, "rooms": 2}],
        "_agents": agents,
    }


def test_write_results(tmp_path: Path) -> None:
    paths = ev.write_results(_fake_result(), tmp_path / "o")
    rows = list(csv.DictReader(paths[0].open()))
    assert [r["seed"] for r in rows] == ["1000", "1001"]
    assert float(rows[0]["policy_mean"]) == 2.0 and float(rows[1]["random_mean"]) == 25.5
    assert rows[1]["rooms"] == "2"
    doc = json.loads(paths[1].read_text())
    assert "_agents" not in doc
    assert doc["agents"][0]["per_seed_mean"] == [2.0, 51.0]


# ------------------------------------------------------------------------------ bookkeeping


class _FakePool:
    """A same-step-autoreset vector env following the pool's sequential seed schedule.

    Episode of seed s lasts 2 + s % 5 steps and pays s + (action sum) on its last step.
    """

    def __init__(self, num_envs: int, seeds: list) -> None:
        self.n, self.seeds = num_envs, seeds
        self.episode = np.zeros(num_envs, np.int64)
        self.t = np.zeros(num_envs, np.int64)
        self.acc = np.zeros(num_envs)
        self.report = None  # a wrong seed to report in final_info, if set

    def _seed(self, i: int) -> int:
        return self.seeds[(i + int(self.episode[i]) * self.n) % len(self.seeds)]

    def reset(self):
        return np.zeros((self.n, 1)), {}

    def step(self, actions):
        rew = np.zeros(self.n)
        done = np.zeros(self.n, bool)
        for i in range(self.n):
            s = self._seed(i)
            self.t[i] += 1
            self.acc[i] += actions[i]
            if self.t[i] >= 2 + s % 5:
                rew[i] = s + self.acc[i]
                done[i] = True
                self.t[i], self.acc[i] = 0, 0.0
                self.episode[i] += 1
        info = {}
        if self.report is not None:
            info = {"final_info": {"seed": np.full(self.n, self.report)}}
        return np.zeros((self.n, 1)), rew, done, np.zeros(self.n, bool), info

    def close(self) -> None:
        pass


@pytest.mark.parametrize("num_envs", [1, 3, 7, 64])
def test_run_episodes_attributes_episodes_to_seeds(monkeypatch, num_envs: int) -> None:
    def fake(suite, schedule, n, workers, obs):
        return _FakePool(n, schedule)

    monkeypatch.setattr(episodes, "make_eval_pool", fake)
    seeds = [1000, 1001, 1002, 1003, 1004]
    out = ev.run_episodes(
        get_suite("paper-10"),
        lambda o: np.zeros(len(o), np.int64),
        seeds,
        3,
        num_envs=num_envs,
        progress=False,
    )
    assert out.shape == (5, 3)
    assert np.array_equal(out, np.repeat(np.array(seeds, float)[:, None], 3, axis=1))


# ------------------------------------------------------------------------------ real engine

SUITE = get_suite("paper-40")
SEEDS = [1000, 1001, 1002, 1003, 1004]


def _pool_available() -> bool:
    from rogue_gym import _native

    return hasattr(_native, "Pool")


needs_pool = pytest.mark.skipif(not _pool_available(), reason="the pool binding is not built")


def _run(backend: str, num_workers=None, num_envs: int = 4, policy=None, suite=SUITE) -> np.ndarray:
    return ev.run_episodes(
        suite,
        policy or ev.RandomPolicy(),
        SEEDS,
        2,
        num_envs=num_envs,
        num_workers=num_workers,
        policy_seed=7,
        progress=False,
        backend=backend,
    )


def test_inprocess_is_deterministic() -> None:
    a = _run("inprocess")
    assert a.shape == (5, 2)
    assert np.array_equal(a, _run("inprocess"))
    assert not np.array_equal(
        a,
        ev.run_episodes(
            SUITE,
            ev.RandomPolicy(),
            SEEDS,
            2,
            num_envs=4,
            policy_seed=8,
            progress=False,
            backend="inprocess",
        ),
    )


@needs_pool
def test_pool_is_deterministic_and_independent_of_workers() -> None:
    one = _run("pool", num_workers=1)
    assert np.array_equal(one, _run("pool", num_workers=1))
    assert np.array_equal(one, _run("pool", num_workers=2))


@needs_pool
def test_few_episodes_keep_a_worker_multiple() -> None:
    # 3 episodes with 2 workers: 2 envs (a multiple of 2), not 3.
    out = ev.run_episodes(
        SUITE, ev.RandomPolicy(), SEEDS[:3], 1, num_envs=64, num_workers=2, progress=False
    )
    assert out.shape == (3, 1) and not np.isnan(out).any()


@needs_pool
def test_pool_matches_inprocess_engine() -> None:
    assert np.array_equal(_run("pool", num_workers=2), _run("inprocess"))


@needs_pool
def test_original_seeding_plays_alike_in_the_pool_and_in_process() -> None:
    original = get_suite("paper-40-original")
    here = _run("inprocess", suite=original)
    assert np.array_equal(_run("pool", num_workers=1, suite=original), here)
    assert np.array_equal(_run("pool", num_workers=2, suite=original), here)
    assert not np.array_equal(here, _run("inprocess"))


def test_seed_manifest_describes_each_seed() -> None:
    rows = ev.seed_manifest(SUITE, SEEDS)
    assert [r["seed"] for r in rows] == SEEDS
    for r in rows:
        assert r["rooms"] + r["gone_rooms"] == 4
        assert r["dark_rooms"] <= r["rooms"] and r["hidden_doors"] <= r["doors"]
        assert r["stairs_distance_unhidden"] is not None
    assert rows == ev.seed_manifest(SUITE, SEEDS)
    hard = ev.seed_manifest(get_suite("rogue-80x24-enemies"), [1000])
    assert hard[0]["rooms"] + hard[0]["gone_rooms"] == 9


def test_cli_manifest_only(tmp_path: Path, capsys) -> None:
    rc = ev.main(
        ["--suite", "paper-10", "--manifest-only", "--seeds-limit", "4", "--out", str(tmp_path)]
    )
    assert rc == 0
    rows = list(csv.DictReader((tmp_path / "manifest.csv").open()))
    assert [int(r["seed"]) for r in rows] == [1000, 1001, 1002, 1003]
    assert len(json.loads((tmp_path / "manifest.json").read_text())) == 4
    assert "stairs_distance" in capsys.readouterr().out


def test_cli_policy_with_random_baseline(tmp_path: Path, capsys) -> None:
    pol = tmp_path / "always_right.py"
    pol.write_text("import numpy as np\ndef act(obs):\n    return np.full(len(obs), 4)\n")
    backend = "pool" if _pool_available() else "inprocess"
    args = [
        "--suite",
        "paper-40",
        "--policy",
        f"{pol}:act",
        "--seeds-limit",
        "3",
        "--episodes-per-seed",
        "2",
        "--num-envs",
        "4",
        "--out",
        str(tmp_path / "o"),
        "--no-progress",
        "--backend",
        backend,
    ]
    assert ev.main(args) == 0
    out = capsys.readouterr().out
    assert "random:" in out and "bootstrap CI across 3 seeds" in out
    doc = json.loads((tmp_path / "o" / "summary.json").read_text())
    # The policy, then the random and the reference agent on the same seeds.
    assert [a["name"] for a in doc["agents"]] == [f"{pol}:act", "random", "reference"]
    assert doc["suite"]["digest"] == SUITE.digest()
    assert np.asarray(doc["agents"][0]["returns"]).shape == (3, 2)
    # A deterministic policy on one seed: every episode of that seed is the same.
    assert all(len(set(r)) == 1 for r in doc["agents"][0]["returns"])
    rows = list(csv.DictReader((tmp_path / "o" / "per_seed.csv").open()))
    assert {"policy_mean", "random_mean", "reference_mean", "rooms", "stairs_distance"} <= set(
        rows[0]
    )
    assert len(rows) == 3


class _ObsPolicy:
    """Deterministic and observation-dependent: exercises the observations themselves."""

    def __init__(self) -> None:
        self.seen: list = []

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        self.seen.append((obs.shape, obs.dtype))
        flat = obs.reshape(len(obs), -1).astype(np.int64)
        return (flat * np.arange(1, flat.shape[1] + 1)).sum(axis=1) % ev.NUM_ACTIONS


@pytest.mark.parametrize(
    ("obs", "shape", "dtype"),
    [
        ("symbol_onehot:float32", (17, 16, 32), np.float32),
        ("symbol_onehot", (17, 16, 32), np.uint8),
        ("symbol_index", (16, 32), np.uint8),
    ],
)
def test_policy_gets_the_requested_observation(obs: str, shape: tuple, dtype) -> None:
    results = []
    for backend in ["inprocess", "pool"] if _pool_available() else ["inprocess"]:
        pol = _ObsPolicy()
        out = ev.run_episodes(
            SUITE, pol, SEEDS[:2], 1, num_envs=2, obs=obs, progress=False, backend=backend
        )
        assert set(pol.seen) == {((2, *shape), np.dtype(dtype))}
        results.append(out)
    # Observation-dependent actions: the pool's observations equal the in-process engine's.
    assert all(np.array_equal(results[0], r) for r in results)


def test_run_episodes_checks_the_played_seeds(monkeypatch) -> None:
    def fake(suite, schedule, n, workers, obs):
        pool = _FakePool(n, schedule)
        pool.report = 7  # never a scheduled seed
        return pool

    monkeypatch.setattr(episodes, "make_eval_pool", fake)
    with pytest.raises(RuntimeError, match="played seed 7"):
        ev.run_episodes(
            get_suite("paper-10"),
            lambda o: np.zeros(len(o), np.int64),
            [1000, 1001],
            1,
            num_envs=2,
            progress=False,
        )


def test_example_policy_runs_and_is_deterministic() -> None:
    root = Path(__file__).resolve().parents[2]
    spec = f"{root / 'benchmarks' / 'example_policies.py'}:StairsSeeker"
    runs = [
        ev.run_episodes(
            SUITE,
            ev.load_policy(spec),
            SEEDS[:2],
            2,
            num_envs=4,
            obs="symbol_index",
            progress=False,
            backend="inprocess",
        )
        for _ in range(2)
    ]
    assert runs[0].shape == (2, 2) and np.array_equal(runs[0], runs[1])
