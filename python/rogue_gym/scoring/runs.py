"""Statistics across training runs (Agarwal et al., NeurIPS 2021, the methods of ``rliable``).

A method is trained several times (learner seeds: *runs*) and each run is scored on the same
seeds of a suite (*tasks*: each test seed is one). Its scores form a ``(runs, seeds)`` matrix;
the aggregates summarise the whole matrix:

* **IQM**: the mean of the middle 50% of all scores (``scipy.stats.trim_mean`` at 25%):
  robust to outlying runs and seeds, and more efficient than the median;
* **median**, **mean**, and the **optimality gap**: the mean shortfall below ``gamma`` (1 for
  normalized scores: the reference agent), so lower is better.

Each comes with a **stratified bootstrap** interval: a resample draws, for every seed on its
own, as many runs as there are, with replacement (runs are the random draw; the seeds are
fixed tasks). A **performance profile** is the fraction of all scores above each threshold
``tau`` (with the same intervals). Two methods are compared by the **probability of
improvement** ``P(X > Y)``: per seed, the Mann-Whitney U statistic over ``runs_X x runs_Y``
(ties count half), averaged over seeds, with a stratified interval; and by a paired test on the same seeds (Wilcoxon's
signed-rank test on the per-seed means over runs, ``scipy.stats.wilcoxon``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Dict, Iterable, Tuple

import numpy as np

__all__ = [
    "AGGREGATES",
    "Interval",
    "iqm",
    "optimality_gap",
    "paired_test",
    "performance_profile",
    "probability_of_improvement",
    "stratified_bootstrap",
]


def iqm(scores: np.ndarray) -> float:
    """Interquartile mean of every score of ``scores`` (any shape): the mean of the sorted
    scores without the lowest and the highest quarter (``int(n / 4)`` each), exactly
    ``scipy.stats.trim_mean(scores, 0.25)`` (a test holds them equal), without scipy."""
    x = np.sort(np.asarray(scores, np.float64).ravel())
    if x.size == 0:
        raise ValueError("iqm needs at least one score")
    cut = int(0.25 * x.size)
    return float(x[cut : x.size - cut].mean())


def optimality_gap(scores: np.ndarray, gamma: float = 1.0) -> float:
    """Mean shortfall of the scores below ``gamma`` (scores above count as ``gamma``)."""
    return float(np.mean(gamma - np.minimum(np.asarray(scores, np.float64), gamma)))


#: The aggregates reported for a method, by name.
AGGREGATES: Dict[str, Callable[[np.ndarray], float]] = {
    "iqm": iqm,
    "median": lambda s: float(np.median(s)),
    "mean": lambda s: float(np.mean(s)),
    "optimality_gap": optimality_gap,
}


@dataclass(frozen=True)
class Interval:
    """A point estimate with its bootstrap interval."""

    value: float
    low: float
    high: float

    def to_json(self) -> Dict[str, float]:
        """``{"value", "low", "high"}``."""
        return {"value": self.value, "low": self.low, "high": self.high}

    def text(self, digits: int = 3) -> str:
        """``value [low, high]``."""
        return f"{self.value:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}]"


def _resample_runs(scores: np.ndarray, reps: int, seed: int) -> np.ndarray:
    """``reps`` stratified resamples of a ``(runs, seeds)`` matrix: ``(reps, runs, seeds)``."""
    runs, seeds = scores.shape
    rng = np.random.default_rng(seed)
    pick = rng.integers(0, runs, size=(reps, runs, seeds))
    return scores[pick, np.arange(seeds)[None, None, :]]


def stratified_bootstrap(
    scores: np.ndarray,
    stat: Callable[[np.ndarray], float],
    confidence: float = 0.95,
    reps: int = 2000,
    seed: int = 0,
) -> Interval:
    """``stat`` of a ``(runs, seeds)`` matrix with its stratified bootstrap interval
    (percentiles of ``stat`` over ``reps`` resamples that draw runs seed by seed)."""
    x = np.asarray(scores, np.float64)
    if x.ndim != 2 or 0 in x.shape:
        raise ValueError(f"scores must be a (runs, seeds) matrix, got shape {x.shape}")
    value = stat(x)
    if x.shape[0] == 1:
        return Interval(value, value, value)  # one run: nothing to resample
    boot = np.array([stat(r) for r in _resample_runs(x, reps, seed)])
    alpha = (1.0 - confidence) / 2.0
    low, high = np.quantile(boot, [alpha, 1.0 - alpha])
    return Interval(value, float(min(low, value)), float(max(high, value)))


def performance_profile(
    scores: np.ndarray,
    taus: Iterable[float],
    confidence: float = 0.95,
    reps: int = 2000,
    seed: int = 0,
) -> list[Interval]:
    """The fraction of scores above each ``tau``, with stratified bootstrap intervals."""
    x = np.asarray(scores, np.float64)

    def above(t: float) -> Callable[[np.ndarray], float]:
        return lambda s: float(np.mean(s > t))

    return [stratified_bootstrap(x, above(float(t)), confidence, reps, seed) for t in taus]


def _poi(x: np.ndarray, y: np.ndarray) -> float:
    """Mean over seeds of P(X > Y) from the runs of each, ties counting half: per seed, the
    Mann-Whitney U statistic of X over ``runs_X x runs_Y`` (what ``scipy.stats.mannwhitneyu``
    returns, a test holds them equal), counted over every pair at once."""
    gt = (x[:, None, :] > y[None, :, :]).mean(axis=(0, 1))
    eq = (x[:, None, :] == y[None, :, :]).mean(axis=(0, 1))
    return float((gt + 0.5 * eq).mean())


def probability_of_improvement(
    x: np.ndarray, y: np.ndarray, confidence: float = 0.95, reps: int = 1000, seed: int = 0
) -> Interval:
    """``P(X > Y)`` of two ``(runs, seeds)`` matrices on the same seeds, with a stratified
    bootstrap interval (the runs of each method resampled seed by seed)."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    if x.ndim != 2 or y.ndim != 2 or x.shape[1] != y.shape[1]:
        raise ValueError(
            f"need (runs, seeds) matrices on the same seeds, got {x.shape} and {y.shape}"
        )
    value = _poi(x, y)
    if x.shape[0] == 1 and y.shape[0] == 1:
        return Interval(value, value, value)
    bx = _resample_runs(x, reps, seed)
    by = _resample_runs(y, reps, seed + 1)
    boot = np.array([_poi(a, b) for a, b in zip(bx, by)])
    alpha = (1.0 - confidence) / 2.0
    low, high = np.quantile(boot, [alpha, 1.0 - alpha])
    return Interval(value, float(min(low, value)), float(max(high, value)))


def paired_test(x: np.ndarray, y: np.ndarray) -> Tuple[float, float, float]:
    """Wilcoxon's signed-rank test of the per-seed means (over runs) of two methods on the
    same seeds: ``(mean difference x - y, statistic, two-sided p-value)``; a p-value of 1
    where every seed ties."""
    from scipy.stats import wilcoxon

    a = np.asarray(x, np.float64).mean(axis=0)
    b = np.asarray(y, np.float64).mean(axis=0)
    diff = a - b
    if not np.any(diff):
        return 0.0, 0.0, 1.0
    res = wilcoxon(a, b)
    return float(diff.mean()), float(res.statistic), float(res.pvalue)
