"""Each env's episode so far (its seed and the actions it took), kept by the front on every
path (reset, partial reset, step, ``recv``) in the call state
(:class:`rogue_gym.kinds.view.CallState`), for a kind that rebuilds frames by replay (the
native game: workers do not ship screens)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Optional

import numpy as np

if TYPE_CHECKING:
    from .result import Result

__all__ = ["EpisodeLog"]


class EpisodeLog:
    """Per env: the seed of its current episode and the actions since it began.

    Cheap to keep (a few vector ops per call); a replay is O(episode length).
    """

    def __init__(self, num_envs: int, max_steps: int) -> None:
        # Room for an episode of ``max_steps`` steps (longer ones overwrite the last entry).
        self.actions = np.zeros((max_steps + 2, num_envs), np.uint8)
        self.length = np.zeros(num_envs, np.int64)
        self.seeds = np.zeros(num_envs, np.uint64)
        #: Envs whose episode began at a SAME_STEP ending step: its seed comes with the next row.
        self.stale = np.zeros(num_envs, bool)

    def record(
        self,
        result: Result,
        actions: Optional[np.ndarray],
        same_step: bool,
        rows: Optional[np.ndarray] = None,
    ) -> None:
        """Follow a call's rows (or only ``rows``, a bool mask: those a partial reset reset).
        ``actions[e]``: the action env ``e`` took (``None`` for a reset). A row of episode
        length 0 is a reset (a reset, an autoreset, a restart); any other is a step."""
        cols = result.cols
        env_ids = result.ids()
        length, seed, ended = cols["episode_length"], cols["seed"].view(np.uint64), result.ended
        if rows is not None:
            env_ids, length, seed, ended = env_ids[rows], length[rows], seed[rows], ended[rows]
        fresh = length == 0
        ids = env_ids[fresh]
        self.length[ids] = 0
        self.seeds[ids] = seed[fresh]
        self.stale[ids] = False
        if actions is None:
            return
        stepped = ~fresh
        ids = env_ids[stepped]
        going = ~ended[stepped]
        fix = self.stale[ids] & going
        self.seeds[ids[fix]] = seed[stepped][fix]
        self.stale[ids[fix]] = False
        pos = np.minimum(self.length[ids], self.actions.shape[0] - 1)
        self.actions[pos, ids] = actions[ids]
        self.length[ids] += 1
        if same_step:  # an ended row's env began its next episode already (seed unknown yet)
            done = ids[~going]
            self.length[done] = 0
            self.stale[done] = True

    def episode(self, env: int) -> tuple[int, np.ndarray]:
        """Env ``env``'s current episode: its seed and its actions so far."""
        return int(self.seeds[env]), self.actions[: int(self.length[env]), env]
