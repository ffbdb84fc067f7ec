"""What the benchmark reports: the reference agent (deterministic, floor 2 on a seed range),
normalized scores, the train-test gap, statistics across runs with known answers (IQM, the
stratified bootstrap's coverage, the probability of improvement, the paired test), the
versions a result records and the refusal to mix them, and ``aggregate``/``compare`` on small
runs made here."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from rogue_gym import evaluate as ev
from rogue_gym.agents import ReferenceAgent
from rogue_gym.scoring import aggregate, runs
from rogue_gym.scoring.episodes import run_episodes
from rogue_gym.scoring.reports import strata_rows, write_results
from rogue_gym.scoring.stats import MIN_MARGIN, gap_ci, normalized
from rogue_gym.scoring.versions import mismatches
from rogue_gym.suites import get_suite

# ------------------------------------------------------------------------------ statistics


def test_iqm_of_a_known_set_and_as_scipy_computes_it() -> None:
    # 8 scores: the lowest two (-50, 1) and the highest two (6, 100) go: the mean of 2..5.
    assert runs.iqm(np.array([100.0, 1, 2, 3, 4, 5, 6, -50])) == 3.5
    scipy_stats = pytest.importorskip("scipy.stats")
    rng = np.random.default_rng(0)
    for n in (1, 3, 7, 40, 101):
        x = rng.exponential(3.0, size=n)
        assert runs.iqm(x) == pytest.approx(scipy_stats.trim_mean(x, 0.25))


def test_optimality_gap_counts_only_the_shortfall() -> None:
    assert runs.optimality_gap(np.array([0.5, 1.0, 2.0])) == pytest.approx(0.5 / 3)


def test_the_stratified_interval_covers_the_true_mean_about_as_often_as_it_says() -> None:
    # Runs are draws around each seed's own mean; the interval is about the mean over runs.
    rng = np.random.default_rng(3)
    seed_means = rng.uniform(0.0, 1.0, size=12)
    truth = seed_means.mean()
    trials, covered = 100, 0
    for t in range(trials):
        scores = seed_means + rng.normal(0.0, 0.3, size=(6, 12))
        iv = runs.stratified_bootstrap(scores, np.mean, 0.95, reps=400, seed=t)
        assert iv.low <= iv.value <= iv.high
        covered += iv.low <= truth <= iv.high
    # A percentile bootstrap of 6 runs undercovers a little; far below 95% is a bug.
    assert 80 <= covered <= 100, covered


def test_probability_of_improvement_and_the_paired_test() -> None:
    rng = np.random.default_rng(1)
    a = rng.normal(0.0, 1.0, size=(5, 20))
    better = a + 10.0
    assert runs.probability_of_improvement(better, a, reps=100).value == 1.0
    assert runs.probability_of_improvement(a, better, reps=100).value == 0.0
    same = runs.probability_of_improvement(a, a, reps=100)
    assert same.value == pytest.approx(0.5)
    diff, _, p = runs.paired_test(better, a)
    assert diff == pytest.approx(10.0) and p < 1e-4
    assert runs.paired_test(a, a) == (0.0, 0.0, 1.0)
    # Per seed, P(X > Y) is the Mann-Whitney U of X over the pairs of runs.
    scipy_stats = pytest.importorskip("scipy.stats")
    x, y = rng.integers(0, 4, size=(4, 3)).astype(float), rng.integers(0, 4, size=(3, 3))
    u = [scipy_stats.mannwhitneyu(x[:, j], y[:, j]).statistic / 12 for j in range(3)]
    assert runs.probability_of_improvement(x, y, reps=10).value == pytest.approx(np.mean(u))


def test_normalized_scores_and_the_floor_of_their_margin() -> None:
    got = normalized(np.array([50.0, 30.0, 12.0]), np.array([10.0, 10.0, 10.0]), [90.0, 30.0, 11.0])
    assert got.tolist() == [0.5, 1.0, 2.0 / MIN_MARGIN]


def test_the_gap_and_its_interval() -> None:
    gap, lo, hi = gap_ci(np.full(10, 5.0), np.full(30, 2.0))
    assert (gap, lo, hi) == (3.0, 3.0, 3.0)
    gap, lo, hi = gap_ci(np.arange(10.0), np.arange(30.0))
    assert gap == pytest.approx(4.5 - 14.5) and lo < gap < hi


def test_strata_split_seeds_by_the_manifest() -> None:
    manifest = [
        {
            "dark_rooms": d,
            "maze_rooms": 0,
            "hidden_doors": h,
            "hidden_passages": 0,
            "stairs_distance": None if h else w,
            "stairs_distance_unhidden": w,
        }
        for d, h, w in [(0, 0, 3), (1, 0, 9), (1, 1, 20), (0, 0, 30)]
    ]
    rows = {r["stratum"]: r for r in strata_rows(manifest, {"x": np.array([1.0, 2.0, 3.0, 4.0])})}
    assert rows["all seeds"] == {"stratum": "all seeds", "seeds": 4, "x": 2.5}
    assert rows["a dark room"]["x"] == 2.5 and rows["no dark room"]["x"] == 2.5
    assert rows["stairs behind a search"]["seeds"] == 1
    assert "a maze" not in rows  # no seed has one


# ------------------------------------------------------------------------------ versions


def _doc(engine: int = 1, digest: str = "d") -> dict:
    return {
        "versions": {
            "package": "0",
            "engine": engine,
            "suite": "s",
            "suite_digest": digest,
            "seeding": "mixed",
        }
    }


def test_results_of_other_versions_are_named_not_mixed(tmp_path: Path) -> None:
    assert mismatches([_doc(), _doc()], ["a", "b"]) == []
    (bad,) = mismatches([_doc(), _doc(engine=2)], ["a", "b"])
    assert bad == "engine differs (a: 1, b: 2)"
    assert "records no versions" in mismatches([_doc(), {}], ["a", "b"])[0]
    for name, doc in (("a", _doc()), ("b", _doc(engine=2))):
        (tmp_path / name).mkdir()
        doc["settings"] = {"seeds": [1, 2]}
        (tmp_path / name / "summary.json").write_text(json.dumps(doc))
    dirs = [tmp_path / "a", tmp_path / "b"]
    with pytest.raises(ValueError, match=r"(?s)engine differs.*--allow-mixed"):
        aggregate.load_runs(dirs)
    assert len(aggregate.load_runs(dirs, allow_mixed=True)) == 2
    assert ev.main(["aggregate", *map(str, dirs)]) == 2


# ------------------------------------------------------------------------------ the reference agent


def test_the_reference_agent_plays_one_trajectory_whatever_the_layout() -> None:
    suite = get_suite("paper-40")
    seeds = list(range(1400, 1406))
    got = [
        run_episodes(
            suite,
            ReferenceAgent(),
            seeds,
            2,
            num_envs=n,
            num_workers=w,
            obs="symbol_index",
            progress=False,
        )
        for n, w in ((6, 1), (4, 2))
    ]
    assert np.array_equal(got[0], got[1])
    assert np.array_equal(got[0][:, 0], got[0][:, 1]), "every episode of a seed is the same"


def test_the_reference_agent_reaches_floor_2_far_above_the_random_agent() -> None:
    # Seeds it was never looked at on (its design used 1000-1063).
    suite = get_suite("paper-40")
    seeds = list(range(1900, 1924))
    floors = np.zeros((len(seeds), 1), np.int64)
    ref = run_episodes(
        suite,
        ReferenceAgent(),
        seeds,
        1,
        num_envs=12,
        obs="symbol_index",
        progress=False,
        max_floor=floors,
    )
    rnd = run_episodes(suite, ev.RandomPolicy(), seeds, 2, num_envs=12, progress=False)
    assert (floors >= 2).mean() >= 0.9
    assert ref.mean() >= 3 * rnd.mean()


def test_the_reference_agent_refuses_other_observations() -> None:
    with pytest.raises(ValueError, match="symbol_index"):
        ReferenceAgent()(np.zeros((2, 17, 16, 32), np.uint8))


# ------------------------------------------------------------------------------ end to end


class _Noisy:
    """The reference agent with a share of random actions: a 'method' whose runs differ."""

    required_obs = "symbol_index"

    def __init__(self, eps: float) -> None:
        self.eps, self.ref = eps, ReferenceAgent()

    def seed(self, s: int) -> None:
        self.rng = np.random.default_rng(s)

    def episodes_ended(self, mask: np.ndarray) -> None:
        self.ref.episodes_ended(mask)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        a = self.ref(obs)
        flip = self.rng.random(len(a)) < self.eps
        a[flip] = self.rng.integers(0, 11, int(flip.sum()))
        return a


def test_evaluate_then_aggregate_and_compare_runs(tmp_path: Path, capsys) -> None:
    # The paper's game with short episodes: the whole path, in seconds.
    suite = dataclasses.replace(get_suite("paper-10"), name="paper-10-short", max_steps=100)
    # Method A: two runs, training seeds too; method B: one run, test seeds only.
    for eps, run in ((0.2, 0), (0.2, 1), (0.7, 0)):
        r = ev.evaluate(
            suite,
            f"noisy-{eps}",
            policy=_Noisy(eps),
            num_envs=6,
            num_workers=2,
            seeds_limit=3,
            episodes_per_seed=2,
            policy_seed=run,
            progress=False,
            with_train=eps < 0.5,
        )
        write_results(r, tmp_path / f"e{eps}-{run}")
    doc = json.loads((tmp_path / "e0.2-0" / "summary.json").read_text())
    assert doc["versions"]["engine"] >= 1 and doc["versions"]["suite"] == "paper-10-short"
    assert [a["name"] for a in doc["agents"]] == ["noisy-0.2", "random", "reference"]
    assert len(doc["train_agents"]) == 3 and len(doc["settings"]["train_seeds"]) == 3
    norm = doc["normalized"]["test"]
    assert norm["ci_low"] <= norm["mean"] <= norm["ci_high"] and len(norm["per_seed"]) == 3
    assert set(doc["gap"]) == {"raw", "normalized"}
    assert (tmp_path / "e0.2-0" / "per_seed_train.csv").is_file()
    good = sorted(map(str, tmp_path.glob("e0.2-*")))
    bad = sorted(map(str, tmp_path.glob("e0.7-*")))
    out = tmp_path / "agg"
    assert ev.main(["aggregate", *good, "--out", str(out)]) == 0
    rep = json.loads((out / "aggregate.json").read_text())
    assert rep["runs"] == 2 and rep["seeds"] == 3
    iq = rep["test"]["iqm"]
    assert iq["low"] <= iq["value"] <= iq["high"]
    assert {"train", "gap", "profile", "strata"} <= set(rep)
    assert (out / "performance_profile.png").stat().st_size > 1000
    assert ev.main(["compare", "--a", *good, "--b", *bad, "--out", str(out)]) == 0
    cmp_ = json.loads((out / "compare.json").read_text())
    assert cmp_["probability_of_improvement"]["value"] > 0.5
    assert "P(A > B)" in capsys.readouterr().out
