"""Statistics of one evaluation: the mean over seeds with a bootstrap interval across seeds,
scores normalized between the random and the reference agent, and the train-test gap."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, Optional, Tuple

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["MIN_MARGIN", "AgentResult", "bootstrap_ci", "gap_ci", "normalized"]


def bootstrap_ci(
    values: ArrayLike,
    confidence: float = 0.95,
    n_resamples: int = 10_000,
    seed: int = 0,
) -> Tuple[float, float, float]:
    """Percentile-bootstrap confidence interval of the mean of ``values``.

    ``values`` are per-seed means (one number per test seed): the interval is across seeds.
    The resampling RNG is ``numpy.random.default_rng(seed)``, so the result is reproducible.

    Returns ``(mean, low, high)``. One value gives a zero-width interval at that value; no
    value raises ``ValueError``.
    """
    x = np.asarray(values, dtype=np.float64).ravel()
    if x.size == 0:
        raise ValueError("bootstrap_ci needs at least one value")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    mean = float(x.mean())
    if x.size == 1 or np.all(x == x[0]):
        return mean, mean, mean
    rng = np.random.default_rng(seed)
    means = np.empty(n_resamples, dtype=np.float64)
    # Chunked so that 10k resamples of 1000 seeds stay ~ 8 MB at a time.
    chunk = max(1, 1_000_000 // x.size)
    for start in range(0, n_resamples, chunk):
        stop = min(n_resamples, start + chunk)
        idx = rng.integers(0, x.size, size=(stop - start, x.size))
        means[start:stop] = x[idx].mean(axis=1)
    alpha = (1.0 - confidence) / 2.0
    low, high = np.quantile(means, [alpha, 1.0 - alpha])
    # Quantiles of a finite resample can miss the sample mean by rounding only when the
    # interval is degenerate; clamp so that low <= mean <= high always holds.
    return mean, float(min(low, mean)), float(max(high, mean))


@dataclass
class AgentResult:
    """Scores of one agent on a suite's (possibly limited) test seeds."""

    name: str
    returns: np.ndarray  # (seeds, episodes)
    mean: float
    ci_low: float
    ci_high: float
    seed_std: float
    #: Each episode's deepest floor, ``(seeds, episodes)``, where the run recorded it.
    max_floor: Optional[np.ndarray] = None

    @classmethod
    def from_returns(
        cls, name: str, returns: np.ndarray, confidence: float, bootstrap_seed: int
    ) -> AgentResult:
        """Summarise ``(seeds, episodes)`` returns: per-seed means, then the bootstrap CI."""
        per_seed = returns.mean(axis=1)
        mean, lo, hi = bootstrap_ci(per_seed, confidence=confidence, seed=bootstrap_seed)
        std = float(per_seed.std(ddof=1)) if per_seed.size > 1 else 0.0
        return cls(name, returns, mean, lo, hi, std)

    def floor_rate(self, floor: int = 2) -> Optional[float]:
        """The share of episodes that reached ``floor`` (averaged seed by seed), if the run
        recorded floors."""
        if self.max_floor is None:
            return None
        return float((self.max_floor >= floor).mean(axis=1).mean())

    def line(self, confidence: float) -> str:
        """``name: mean [lo, hi] (95% CI across N seeds)``, and the floor-2 rate."""
        half = (self.ci_high - self.ci_low) / 2.0
        rate = self.floor_rate(2)
        floors = "" if rate is None else f"; floor 2 reached in {rate:.1%}"
        return (
            f"{self.name}: {self.mean:.2f} ± {half:.2f} "
            f"[{self.ci_low:.2f}, {self.ci_high:.2f}] "
            f"({confidence:.0%} bootstrap CI across {self.returns.shape[0]} seeds, "
            f"{self.returns.shape[1]} episodes each{floors})"
        )

    def to_json(self) -> Dict[str, Any]:
        """JSON-able summary with the raw returns."""
        return {
            "name": self.name,
            "mean": self.mean,
            "ci_low": self.ci_low,
            "ci_high": self.ci_high,
            "per_seed_std": self.seed_std,
            "per_seed_mean": self.returns.mean(axis=1).tolist(),
            "returns": self.returns.tolist(),
            "reached_floor_2": self.floor_rate(2),
            "max_floor": None if self.max_floor is None else self.max_floor.tolist(),
        }


#: The smallest reference-over-random margin a seed's normalized score divides by: where the
#: reference agent beats the random agent by less (a seed neither gets far on), the seed's
#: normalized score would be noise blown up, so the margin is taken as this (a fifth of a
#: floor's stair reward on the paper's suites).
MIN_MARGIN = 10.0


def normalized(scores: ArrayLike, random: ArrayLike, reference: ArrayLike) -> np.ndarray:
    """Per-seed normalized scores: ``(score - random) / (reference - random)`` with the seed's
    random and reference means (0: the random agent, 1: the reference agent), the margin at
    least :data:`MIN_MARGIN`. ``scores`` may carry leading axes (runs) before the seeds."""
    rnd = np.asarray(random, np.float64)
    margin = np.maximum(np.asarray(reference, np.float64) - rnd, MIN_MARGIN)
    return (np.asarray(scores, np.float64) - rnd) / margin


def gap_ci(
    train: ArrayLike,
    test: ArrayLike,
    confidence: float = 0.95,
    n_resamples: int = 10_000,
    seed: int = 0,
) -> Tuple[float, float, float]:
    """The generalization gap, mean over training seeds minus mean over test seeds, with a
    bootstrap interval that resamples each set of per-seed means on its own."""
    a = np.asarray(train, np.float64).ravel()
    b = np.asarray(test, np.float64).ravel()
    if a.size == 0 or b.size == 0:
        raise ValueError("gap_ci needs per-seed means of both the training and the test seeds")
    rng = np.random.default_rng(seed)
    ma = a[rng.integers(0, a.size, size=(n_resamples, a.size))].mean(axis=1)
    mb = b[rng.integers(0, b.size, size=(n_resamples, b.size))].mean(axis=1)
    gap = float(a.mean() - b.mean())
    alpha = (1.0 - confidence) / 2.0
    low, high = np.quantile(ma - mb, [alpha, 1.0 - alpha])
    return gap, float(min(low, gap)), float(max(high, gap))
