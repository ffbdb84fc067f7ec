"""Example policies for ``python -m rogue_gym.evaluate`` (the policy interface in practice).

``StairsSeeker`` is a hand-written heuristic, not a learned agent: it reads the
``symbol_index`` observation, walks toward the stairs when it has seen them (and presses ``>``
on them), otherwise toward visible gold, and otherwise explores at random. It shows how a
policy plugs into the evaluator and gives a second reference point besides the random agent::

    python -m rogue_gym.evaluate --suite paper-40 --obs symbol_index \\
        --policy benchmarks/example_policies.py:StairsSeeker

``NoisyReference`` and ``NoisierReference`` are the reference agent with 30% and 60% of its
actions random (from the policy seed): two "methods" whose runs differ, for the worked example
of reporting in ``docs/benchmark.md``.
"""

from __future__ import annotations

from typing import List, Optional, Tuple

import numpy as np

# Symbol indices of the ``symbol_index`` encoding (docs/rules.md §9.1).
PLAYER, STAIRS, GOLD = 1, 5, 13
# Action indices: ". h j k l n b u y > s".
DOWNSTAIRS = 9
MOVE = {
    (-1, 0): 1,
    (0, 1): 2,
    (0, -1): 3,
    (1, 0): 4,
    (1, 1): 5,
    (-1, 1): 6,
    (1, -1): 7,
    (-1, -1): 8,
}


class StairsSeeker:
    """Greedy stairs-then-gold walker with random exploration (seeded, deterministic).

    ``explore`` is the probability of a uniformly random action at any step, which gets it
    around walls and through doorways that the greedy step cannot take diagonally.
    """

    def __init__(self, seed: int = 0, explore: float = 0.3) -> None:
        self.explore = explore
        self.seed(seed)

    def seed(self, seed: int) -> None:
        """Restart the random stream and forget remembered stairs."""
        self._rng = np.random.default_rng(seed)
        self._stairs: List[Optional[Tuple[int, int]]] = []

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """One action per env from ``(N, H, W)`` symbol indices."""
        if obs.ndim != 3:
            raise ValueError("StairsSeeker needs --obs symbol_index ((N, H, W) observations)")
        n = len(obs)
        if len(self._stairs) != n:
            self._stairs = [None] * n
        actions = self._rng.integers(0, 11, size=n, dtype=np.int64)
        explore = self._rng.random(n) < self.explore
        for i in range(n):
            screen = obs[i]
            me = np.argwhere(screen == PLAYER)
            if len(me) == 0:
                continue
            y, x = (int(v) for v in me[0])
            stairs = np.argwhere(screen == STAIRS)
            if len(stairs):
                self._stairs[i] = (int(stairs[0][0]), int(stairs[0][1]))
            target = self._stairs[i]
            if target == (y, x):
                actions[i] = DOWNSTAIRS
                self._stairs[i] = None  # a new floor, or a stale memory: forget it
                continue
            if explore[i]:
                continue
            if target is None:
                gold = np.argwhere(screen == GOLD)
                if len(gold) == 0:
                    continue
                d = np.abs(gold - (y, x)).max(axis=1)
                target = (int(gold[d.argmin()][0]), int(gold[d.argmin()][1]))
            dy, dx = int(np.sign(target[0] - y)), int(np.sign(target[1] - x))
            actions[i] = MOVE[(dx, dy)]
        return actions


class NoisyReference:
    """The reference agent (``rogue_gym.agents.ReferenceAgent``) with a share ``EPS`` of its
    actions replaced by random ones, drawn from the policy seed: a stand-in for a trained
    method whose runs (policy seeds) differ, for the worked example of ``docs/benchmark.md``."""

    EPS = 0.3
    required_obs = "symbol_index"

    def __init__(self) -> None:
        from rogue_gym.agents import ReferenceAgent

        self.ref = ReferenceAgent()
        self.rng = np.random.default_rng(0)

    def seed(self, seed: int) -> None:
        """Restart the random share from ``seed``."""
        self.rng = np.random.default_rng(seed)

    def episodes_ended(self, mask: np.ndarray) -> None:
        """The reference agent's memory of those rows starts afresh."""
        self.ref.episodes_ended(mask)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The reference agent's actions, a share of them random."""
        actions = self.ref(obs)
        flip = self.rng.random(len(actions)) < self.EPS
        actions[flip] = self.rng.integers(0, 11, int(flip.sum()))
        return actions


class NoisierReference(NoisyReference):
    """:class:`NoisyReference` with twice the random share: the weaker "method"."""

    EPS = 0.6
