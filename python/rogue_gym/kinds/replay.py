"""Screens of the native game rebuilt by replay (workers do not ship screens)."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from .. import _native
from .._config import to_json

__all__ = ["ActionHistory"]


class ActionHistory:
    """Per-env action keys since each env's episode start, to rebuild screens by replay.

    A frame is rebuilt by replaying an env's current episode (its seed and recorded actions) on
    an in-process engine. Cheap to record (a few vector ops per step), O(episode length) to
    render.
    """

    def __init__(
        self, config: Mapping[str, Any], max_steps: int, stair_reward: float, num_envs: int
    ) -> None:
        self.config, self.max_steps, self.stair_reward = config, max_steps, stair_reward
        self.actions = np.zeros((max_steps + 2, num_envs), np.uint8)
        self.length = np.zeros(num_envs, np.int64)
        self.seeds = np.zeros(num_envs, np.uint64)
        self.stale = np.zeros(num_envs, bool)

    def on_reset(self, recs: np.ndarray, envs: np.ndarray, seed_known: bool = True) -> None:
        """``envs`` (bool mask) started new episodes, described by ``recs`` if ``seed_known``
        (SAME_STEP ending steps describe the old episode: the seed is taken from the next step)."""
        self.length[envs] = 0
        if seed_known:
            self.seeds[envs] = recs["seed"][envs]
            self.stale[envs] = False
        else:
            self.stale |= envs

    def on_step(self, actions: np.ndarray, stepped: np.ndarray, recs: np.ndarray) -> None:
        """Record ``actions`` of the envs in the ``stepped`` mask (``recs``: this step's records)."""
        if self.stale.any():
            fix = self.stale & ((recs["flags"] & 3) == 0)
            self.seeds[fix] = recs["seed"][fix]
            self.stale &= ~fix
        idx = np.flatnonzero(stepped)
        pos = np.minimum(self.length[idx], self.actions.shape[0] - 1)
        self.actions[pos, idx] = actions[idx]
        self.length[idx] += 1

    def on_rows(
        self, env_ids: np.ndarray, recs: np.ndarray, sent: np.ndarray, same_step: bool
    ) -> None:
        """An async ``recv``: env ``env_ids[r]`` answered with ``recs[r]``; ``sent[e]`` is the
        action last sent to env ``e``. A row of episode length 0 is a reset (``async_reset``,
        an autoreset, a restart); any other is a step with the action sent."""
        fresh = recs["episode_length"] == 0
        ids = env_ids[fresh]
        self.length[ids] = 0
        self.seeds[ids] = recs["seed"][fresh]
        self.stale[ids] = False
        ids, rows = env_ids[~fresh], recs[~fresh]
        going = (rows["flags"] & 3) == 0
        fix = self.stale[ids] & going
        self.seeds[ids[fix]] = rows["seed"][fix]
        self.stale[ids[fix]] = False
        pos = np.minimum(self.length[ids], self.actions.shape[0] - 1)
        self.actions[pos, ids] = sent[ids]
        self.length[ids] += 1
        if same_step:  # an ended row's env began its next episode already (seed unknown yet)
            done = ids[~going]
            self.length[done] = 0
            self.stale[done] = True

    def screen(self, i: int) -> str:
        """The current screen of env ``i``: map rows and status line."""
        game = _native.Game(to_json(self.config), self.max_steps, self.stair_reward)
        game.reset(int(self.seeds[i]))
        for a in self.actions[: int(self.length[i]), i]:
            game.step(int(a))
        return "\n".join([*game.screen(), game.status_line()])
