"""Named, frozen generalization suites .

A suite pins everything that decides a score: the game config (``GameConfig`` JSON), the episode
length, the stair reward, the training seeds and the test seeds. Agents train on
``suite.train_seeds`` and are scored by :mod:`rogue_gym.evaluate` on ``suite.test_seeds``, with
``suite.episodes_per_seed`` episodes per test seed by default.

Suites are **frozen**: ``tests/python/test_suites.py`` hard-codes the sha256 digest of each
suite's canonical JSON (see :meth:`Suite.digest`). Changing what a suite means changes its
digest and fails that test: define a new suite with a new name instead, so published numbers
keep their meaning.

The paper's suites (Kanagawa & Kaneko, CoG 2019) are ``paper-10``, ``paper-20`` and
``paper-40``: 32x16 screen, 2x2 rooms, no monsters, 500-step episodes, reward = gold gained +
50 per new deepest floor, train seeds ``[0, N)``, test seeds ``[1000, 2000)``. They use our
seeding (``"seeding": "mixed"``): the same rules, but each seed maps to a different dungeon than
in the original, so their numbers are re-baselined here.

``paper-10-original``, ``paper-20-original`` and ``paper-40-original`` are the same suites under
``"seeding": "original"``: each seed gives the original's (v0.0.2) dungeon, so scores compare
with the paper's seed for seed (engine/README.md, "Original seeding").
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from typing import Any, Dict, List, Tuple

from ._config import PAPER_CONFIG as _PAPER

__all__ = [
    "PAPER_CONFIG",
    "PAPER_ORIGINAL_CONFIG",
    "SUITES",
    "Suite",
    "get_suite",
    "suite_names",
]

#: The paper's game config without its training ``seed_range`` (a suite names its seeds itself).
PAPER_CONFIG: Dict[str, Any] = {k: v for k, v in _PAPER.items() if k != "seed_range"}

#: The original game's default screen (80x24, 3x3 rooms) with all 26 monsters (the default).
DEFAULT_80X24_CONFIG: Dict[str, Any] = {
    "width": 80,
    "height": 24,
    "hide_dungeon": True,
    "dungeon": {"style": "rogue", "room_num_x": 3, "room_num_y": 3},
}


@dataclass(frozen=True)
class Suite:
    """One frozen generalization suite.

    Attributes:
        name: the suite's unique name (``paper-40``...).
        description: one line for humans (not part of the digest).
        config: the ``GameConfig`` JSON object (no ``seed``/``seed_range``: the evaluator and
            the pool's seed set choose seeds).
        max_steps: episode length (truncation), in agent steps.
        stair_reward: reward for each new deepest floor (added to gold gained).
        train_seeds: ``(lo, hi)``: training seeds are ``range(lo, hi)``.
        test_seeds: ``(lo, hi)``: test seeds are ``range(lo, hi)``.
        episodes_per_seed: default number of evaluation episodes per test seed.
    """

    name: str
    config: Dict[str, Any]
    max_steps: int
    stair_reward: float
    train_seeds: Tuple[int, int]
    test_seeds: Tuple[int, int]
    episodes_per_seed: int = 10
    description: str = field(default="", compare=False)

    def train_seed_list(self) -> List[int]:
        """The training seeds, in increasing order."""
        return list(range(*self.train_seeds))

    def test_seed_list(self) -> List[int]:
        """The test seeds, in increasing order."""
        return list(range(*self.test_seeds))

    def config_json(self) -> str:
        """The game config as compact JSON with sorted keys (what the engine receives)."""
        return json.dumps(self.config, sort_keys=True, separators=(",", ":"))

    def canonical(self) -> Dict[str, Any]:
        """Everything that defines the suite's scores, as a JSON-able dict (no description)."""
        return {
            "name": self.name,
            "config": self.config,
            "max_steps": int(self.max_steps),
            "stair_reward": float(self.stair_reward),
            "train_seeds": list(range(*self.train_seeds)),
            "test_seeds": list(range(*self.test_seeds)),
            "episodes_per_seed": int(self.episodes_per_seed),
        }

    def canonical_json(self) -> str:
        """:meth:`canonical` as compact JSON with sorted keys: the input of :meth:`digest`."""
        return json.dumps(self.canonical(), sort_keys=True, separators=(",", ":"))

    def digest(self) -> str:
        """sha256 hex digest of :meth:`canonical_json`; frozen by the test suite."""
        return hashlib.sha256(self.canonical_json().encode("utf-8")).hexdigest()


#: The paper's game config under the original's seeding: the original's dungeon for each seed.
PAPER_ORIGINAL_CONFIG: Dict[str, Any] = {**PAPER_CONFIG, "seeding": "original"}


def _paper(n: int, original: bool = False) -> Suite:
    return Suite(
        name=f"paper-{n}-original" if original else f"paper-{n}",
        description=(
            f"CoG'19 paper protocol: train seeds [0,{n}), test [1000,2000), 32x16, 2x2 rooms, "
            "no monsters, 500 steps, +50 per new floor"
            + (", the original's dungeons (original seeding)" if original else "")
        ),
        config=PAPER_ORIGINAL_CONFIG if original else PAPER_CONFIG,
        max_steps=500,
        stair_reward=50.0,
        train_seeds=(0, n),
        test_seeds=(1000, 2000),
    )


_ALL = [
    _paper(10),
    _paper(20),
    _paper(40),
    _paper(10, original=True),
    _paper(20, original=True),
    _paper(40, original=True),
    Suite(
        name="rogue-80x24-enemies",
        description=(
            "harder: the original's default 80x24 screen, 3x3 rooms, all 26 monsters, "
            "train [0,40), test [1000,2000), 1000 steps, +50 per new floor"
        ),
        config=DEFAULT_80X24_CONFIG,
        max_steps=1000,
        stair_reward=50.0,
        train_seeds=(0, 40),
        test_seeds=(1000, 2000),
    ),
]

#: All suites by name.
SUITES: Dict[str, Suite] = {s.name: s for s in _ALL}


def suite_names() -> List[str]:
    """Names of all suites, in definition order."""
    return [s.name for s in _ALL]


def get_suite(name: str) -> Suite:
    """The suite called ``name``; ``KeyError`` listing the known names otherwise."""
    try:
        return SUITES[name]
    except KeyError:
        raise KeyError(f"unknown suite {name!r}; known: {', '.join(suite_names())}") from None
