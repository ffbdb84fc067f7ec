"""The benchmark's scripted reference agent: what a sensible player without learning scores.

:class:`ReferenceAgent` reads the symbol map (``symbol_index``: one symbol per cell) and
plays every env of a batch at once with numpy. Per env it keeps a memory of the floor (what
each cell last showed: a dark room's floor and stairs vanish from the screen once left, but
not from the memory), the cells it stood on, the moves that failed and where it searched.
Each step it builds one *distance map* per env (a Dijkstra map: every walkable cell's number
of moves to the nearest goal, under the game's movement rule: no diagonal step onto or off a
door, no corner cutting in passages) and takes the move down it:

* the stairs known: the goal is the stairs, and ``>`` on them;
* else the goal is the frontier: cells it has not stood on with an unknown neighbour
  (unexplored passages, doors, the dark parts of rooms);
* gold on the way counts as :data:`GOLD_PULL` moves nearer than the goal, so a pile a few
  steps off the path is picked up; so does the amulet, where a suite has one;
* nothing left to explore: it searches, where a hidden door or passage is likely (passage dead
  ends first, then along walls), :data:`SEARCH_TURNS` turns at a spot before it moves on.

It is deterministic: its actions are a function of the observations alone, so on a seed it
plays one trajectory whatever the pool's layout (a test checks it). It needs to know where
episodes end: the evaluator calls :meth:`ReferenceAgent.episodes_ended` after each step.

Where it fails (``docs/benchmark.md`` gives the figures by the seed manifest's columns):
stairs behind a secret door or a hidden passage that its searches miss, mazes (dark rooms
that are corridors: slow to explore cell by cell) and dark rooms generally (it must walk
each one to find its stairs). It does not fight: with monsters it walks past or into them.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

__all__ = ["GOLD_PULL", "SEARCH_TURNS", "ReferenceAgent"]

# Symbols (engine-spec §12.1; ``symbol_index`` observations hold these per cell).
_BLANK, _PLAYER, _PASSAGE, _FLOOR, _WALL, _STAIRS, _DOOR, _TRAP = 0, 1, 2, 3, 4, 5, 6, 7
_GOLD, _AMULET = 13, 16
#: Symbols a player may walk on (items are picked up on the way).
_WALKABLE = np.zeros(256, bool)
_WALKABLE[[_PASSAGE, _FLOOR, _STAIRS, _DOOR, _TRAP, *range(8, 17)]] = True

# Actions in the pool's order (". h j k l n b u y > s"): the eight moves as (dy, dx).
_MOVES = (
    (1, 0, -1),
    (2, 1, 0),
    (3, -1, 0),
    (4, 0, 1),
    (5, 1, 1),
    (6, 1, -1),
    (7, -1, 1),
    (8, -1, -1),
)
_DOWN, _SEARCH = 9, 10

#: How many moves nearer than the goal a pile of gold counts: a pile within about that many
#: extra moves of the way is picked up.
GOLD_PULL = 10
#: Searches made in a row at one spot before another is tried.
SEARCH_TURNS = 5
#: A distance no cell reaches (the maps are at most 24 x 80 cells).
_FAR = np.int32(1 << 20)


class ReferenceAgent:
    """The scripted reference agent (see the module docs), over ``symbol_index`` batches.

    ``policy(obs)`` takes ``(N, H, W)`` uint8 symbol maps and returns ``N`` actions.
    """

    #: The observation the evaluator must give it.
    required_obs = "symbol_index"

    def __init__(self) -> None:
        self._shape: Optional[tuple[int, int, int]] = None

    def seed(self, seed: int) -> None:
        """No randomness: accepted for the policy interface."""

    def _start(self, shape: tuple[int, int, int]) -> None:
        n, h, w = shape
        self._shape = shape
        self.memory = np.zeros((n, h, w), np.uint8)
        self.stood = np.zeros((n, h, w), bool)
        self.blocked = np.zeros((n, h, w), bool)
        self.searched = np.zeros((n, h, w), np.int32)
        self.pos = np.full((n, 2), -1, np.int64)
        self.last = np.zeros(n, np.int64)
        self.target = np.full((n, 2), -1, np.int64)
        self.search_left = np.zeros(n, np.int64)

    def forget(self, rows: np.ndarray) -> None:
        """Forget what rows ``rows`` knew of their floor (a new floor, or a new episode)."""
        self.memory[rows] = 0
        self.stood[rows] = False
        self.blocked[rows] = False
        self.searched[rows] = 0
        self.pos[rows] = -1
        self.last[rows] = 0
        self.target[rows] = -1
        self.search_left[rows] = 0

    def episodes_ended(self, mask: np.ndarray) -> None:
        """The episodes of the rows in ``mask`` ended on the last step: their next
        observation is a new episode's first."""
        if self._shape is not None:
            self.forget(np.flatnonzero(mask))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """One action per row of ``obs`` (``(N, H, W)`` symbol indices)."""
        obs = np.asarray(obs)
        if obs.ndim != 3:
            raise ValueError(
                f"ReferenceAgent reads symbol maps (N, H, W), got shape {obs.shape}: "
                "evaluate it with obs='symbol_index'"
            )
        if self._shape != obs.shape:
            self._start(obs.shape)
        n = obs.shape[0]
        rows = np.arange(n)
        # A `>` on the stairs leads to a new floor: its memory starts afresh.
        self.forget(rows[self.last == _DOWN])
        player = obs == _PLAYER
        found = player.reshape(n, -1).argmax(axis=1)
        pos = np.stack(np.unravel_index(found, obs.shape[1:]), axis=1)
        seen = player.reshape(n, -1).any(axis=1)
        self._remember(obs, pos, seen)
        actions = self._plan(pos, seen)
        self.pos = np.where(seen[:, None], pos, -1)
        self.last = actions
        return actions

    def _remember(self, obs: np.ndarray, pos: np.ndarray, seen: np.ndarray) -> None:
        """Fold the screen into the memory; mark where the player stands, and a move that
        failed (the player did not move) as blocked."""
        shown = (obs != _BLANK) & (obs != _PLAYER)
        np.copyto(self.memory, obs, where=shown)
        rows = np.flatnonzero(seen)
        y, x = pos[rows, 0], pos[rows, 1]
        under = self.memory[rows, y, x]
        # What the player stands on was picked up if it was an item; structure stays.
        keep = (under == _STAIRS) | (under == _DOOR) | (under == _PASSAGE) | (under == _TRAP)
        self.memory[rows, y, x] = np.where(keep, under, _FLOOR)
        self.stood[rows, y, x] = True
        moved = (self.last[rows] >= 1) & (self.last[rows] <= 8)
        stuck = moved & (self.pos[rows, 0] == y) & (self.pos[rows, 1] == x)
        for j in np.flatnonzero(stuck):
            _, dy, dx = _MOVES[int(self.last[rows[j]]) - 1]
            ty, tx = int(y[j]) + dy, int(x[j]) + dx
            if 0 <= ty < obs.shape[1] and 0 <= tx < obs.shape[2]:
                self.blocked[rows[j], ty, tx] = True

    def _plan(self, pos: np.ndarray, seen: np.ndarray) -> np.ndarray:
        """Each row's action from its distance map (see the module docs)."""
        n, h, w = self.memory.shape
        rows = np.arange(n)
        mem = self.memory
        walk = _WALKABLE[mem] & ~self.blocked
        py, px = pos[:, 0], pos[:, 1]
        walk[rows, py, px] |= seen
        # Goals and their values: the amulet, the stairs, else the frontier; gold pulls.
        goal = np.full((n, h, w), _FAR, np.int32)
        stairs = mem == _STAIRS
        has_stairs = stairs.reshape(n, -1).any(axis=1)
        unknown = np.pad(mem == _BLANK, ((0, 0), (1, 1), (1, 1)), constant_values=True)
        edge = unknown[:, :-2, 1:-1] | unknown[:, 2:, 1:-1] | unknown[:, 1:-1, :-2]
        edge |= unknown[:, 1:-1, 2:]
        frontier = walk & ~self.stood & edge
        aim = np.where(has_stairs[:, None, None], stairs, frontier)
        goal[aim] = 0
        goal[(mem == _GOLD) & walk] = -GOLD_PULL
        goal[(mem == _AMULET) & walk] = -GOLD_PULL
        explore = (goal < _FAR).reshape(n, -1).any(axis=1)
        # Nothing left to walk to: search where hidden things are likely (the least searched
        # spot first, passage dead ends before the sides of walls).
        spots, extra = self._search_spots(walk)
        lost = ~explore
        goal[lost] = np.where(spots[lost], self.searched[lost] + extra[lost], _FAR)
        moves = _move_masks(walk)
        dist = _distance_map(goal, moves, pos)
        actions = np.full(n, _SEARCH, np.int64)
        here = dist[rows, py, px]
        best = here.copy()
        for i, (action, dy, dx) in enumerate(_MOVES):
            ty, tx = py + dy, px + dx
            inside = (ty >= 0) & (ty < h) & (tx >= 0) & (tx < w)
            ok = inside & moves[i][rows, py, px]
            cand = np.where(ok, dist[rows, np.clip(ty, 0, h - 1), np.clip(tx, 0, w - 1)], _FAR)
            better = cand < best
            actions[better] = action
            best = np.minimum(best, cand)
        on_stairs = mem[rows, py, px] == _STAIRS
        actions[on_stairs & has_stairs] = _DOWN
        # A search spot reached: search there a few turns in a row.
        busy = self.search_left > 0
        actions[busy] = _SEARCH
        searching = (actions == _SEARCH) & seen
        self.search_left[searching & ~busy] = SEARCH_TURNS
        self.search_left[searching] -= 1
        sr = rows[searching]
        self.searched[sr, py[sr], px[sr]] += 1
        actions[~seen] = _SEARCH
        return actions

    def _search_spots(self, walk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cells worth a search, and what each adds to its count of searches: passage dead
        ends (one walkable neighbour) nothing, other cells beside a wall or the unknown
        :data:`SEARCH_TURNS` (they are tried after the dead ends)."""
        mem = self.memory
        _, h, w = walk.shape
        pad_w = np.pad(walk, ((0, 0), (1, 1), (1, 1))).astype(np.int8)
        nbrs = pad_w[:, :-2, 1:-1] + pad_w[:, 2:, 1:-1] + pad_w[:, 1:-1, :-2] + pad_w[:, 1:-1, 2:]
        solid = (mem == _WALL) | (mem == _BLANK)
        pad_s = np.pad(solid, ((0, 0), (1, 1), (1, 1)), constant_values=True)
        near = np.zeros_like(walk)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dy or dx:
                    near |= pad_s[:, 1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
        dead_end = walk & (mem == _PASSAGE) & (nbrs <= 1)
        spots = dead_end | (walk & near & ((mem == _FLOOR) | (mem == _PASSAGE)))
        extra = np.where(dead_end, 0, SEARCH_TURNS).astype(np.int32)
        return spots, extra


def _move_masks(walk: np.ndarray) -> list[np.ndarray]:
    """For each of the eight moves (in :data:`_MOVES` order), where it may be made: the target
    walkable and, for a diagonal move, both cells it passes beside walkable too."""
    n, h, w = walk.shape
    p = np.pad(walk, ((0, 0), (1, 1), (1, 1)))

    def at(dy: int, dx: int) -> np.ndarray:
        return p[:, 1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]

    out = []
    for _, dy, dx in _MOVES:
        ok = walk & at(dy, dx)
        if dy and dx:
            ok = ok & at(dy, 0) & at(0, dx)
        out.append(ok)
    return out


def _distance_map(goal: np.ndarray, moves: list[np.ndarray], pos: np.ndarray) -> np.ndarray:
    """Every cell's least ``goal`` value plus moves to reach it (``goal`` holds the goals'
    values, :data:`_FAR` elsewhere), relaxed until it is exact at each player's cell ``pos``
    and around it: a goal of value ``v`` at ``d`` moves reaches a cell at relaxation ``d``, so
    once the first goal has reached the player, every better one arrives within the spread of
    the goal values (plus one move to the player's neighbours); nothing further is needed."""
    n, h, w = goal.shape
    rows = np.arange(n)
    finite = goal < _FAR
    lo = np.where(finite, goal, _FAR).reshape(n, -1).min(axis=1)
    hi = np.where(finite, goal, -_FAR).reshape(n, -1).max(axis=1)
    margin = np.where(hi >= lo, hi - lo, 0) + 2
    reached = np.full(n, -1)
    dist = goal.copy()
    pad = np.full((n, h + 2, w + 2), _FAR, np.int32)
    for t in range(h * w):
        pad[:, 1:-1, 1:-1] = dist
        new = dist.copy()
        for i, (_, dy, dx) in enumerate(_MOVES):
            nbr = pad[:, 1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w] + 1
            np.minimum(new, nbr, out=new, where=moves[i])
        changed = (new != dist).reshape(n, -1).any(axis=1)
        dist = new
        first = (reached < 0) & (dist[rows, pos[:, 0], pos[:, 1]] < _FAR)
        reached[first] = t
        if not (changed & ((reached < 0) | (t - reached < margin))).any():
            break
    return dist
