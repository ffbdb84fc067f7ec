//! The original's corridors, draw for draw: a spanning tree grown from a random room, then
//! up to `max_extra_edges - 1` extra corridors; each corridor picks its two ends and a turn
//! point, and every cell it writes is registered in order (doors first).

use super::super::floor::{Room, RoomKind};
use crate::config::GameConfig;
use crate::geometry::{Dir, Rect};
use crate::rng::xorshift::XorShift128;

/// The longest leg a corridor walks (a screen is at most 160 cells wide).
const MAX_CORRIDOR_LEG: usize = 1024;

/// What a registered cell becomes: a door (of a normal room) or a passage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Dug {
    /// A door in a normal room's wall.
    Door,
    /// A corridor cell, or the end of a corridor in a maze or at a gone room's junction.
    Passage,
}

/// The slot graph: which slot lies next to which, and in what direction.
struct Graph {
    nx: i32,
    ny: i32,
    connected: Vec<Vec<bool>>,
}

impl Graph {
    fn new(nx: i32, ny: i32) -> Self {
        let n = (nx * ny) as usize;
        Graph {
            nx,
            ny,
            connected: vec![vec![false; n]; n],
        }
    }

    /// The direction from slot `a` to slot `b` when they are neighbours (up, down, left, right).
    fn direction(&self, a: usize, b: usize) -> Option<Dir> {
        let (ax, ay) = (a as i32 % self.nx, a as i32 / self.nx);
        [Dir::Up, Dir::Down, Dir::Left, Dir::Right]
            .into_iter()
            .find(|d| {
                let (dx, dy) = d.delta();
                let (bx, by) = (ax + dx, ay + dy);
                (0..self.nx).contains(&bx)
                    && (0..self.ny).contains(&by)
                    && (bx + by * self.nx) as usize == b
            })
    }

    fn connect(&mut self, a: usize, b: usize) {
        self.connected[a][b] = true;
        self.connected[b][a] = true;
    }

    /// The original's `select_candidate`: among the neighbours of `from` that pass `ok`, in
    /// slot order, the k-th draws `one_in(k + 1)`; the last true one is chosen.
    fn candidate(
        &self,
        from: usize,
        rng: &mut XorShift128,
        ok: impl Fn(usize) -> bool,
    ) -> Option<(usize, Dir)> {
        let n = self.connected.len();
        let mut rank = 0u32;
        let mut chosen = None;
        for to in (0..n).filter(|&to| ok(to)) {
            if let Some(dir) = self.direction(from, to) {
                rank += 1;
                if rng.one_in(rank) {
                    chosen = Some((to, dir));
                }
            }
        }
        chosen
    }
}

/// Digs all corridors of a floor and returns the registered cells in the original's order.
pub(super) fn dig(
    rooms: &[Room],
    cfg: &GameConfig,
    maze_has: &dyn Fn(usize, i32, i32) -> bool,
    rng: &mut XorShift128,
) -> Vec<(i32, i32, Dug)> {
    let (nx, ny) = (cfg.dungeon.room_num_x, cfg.dungeon.room_num_y);
    let n = rooms.len();
    let mut graph = Graph::new(nx, ny);
    let mut out = Vec::new();
    let mut in_tree = vec![false; n];
    let mut tree_size = 1;
    let mut cur = rng.below_usize(n);
    in_tree[cur] = true;
    while tree_size < n {
        match graph.candidate(cur, rng, |r| !in_tree[r]) {
            Some((next, dir)) => {
                in_tree[next] = true;
                tree_size += 1;
                graph.connect(cur, next);
                connect(rooms, maze_has, cur, next, dir, rng, &mut out);
            }
            None => {
                // The n-th room of the tree, in slot order.
                let k = rng.below_usize(tree_size);
                cur = (0..n).filter(|&r| in_tree[r]).nth(k).unwrap_or(cur);
            }
        }
    }
    let extra = rng.below_u32(cfg.dungeon.max_extra_edges);
    for _ in 0..extra {
        let a = rng.below_usize(n);
        let linked = graph.connected[a].clone();
        if let Some((b, dir)) = graph.candidate(a, rng, |r| !linked[r]) {
            graph.connect(a, b);
            connect(rooms, maze_has, a, b, dir, rng, &mut out);
        }
    }
    out
}

/// One corridor from room `a` to its neighbour `b` in `dir`, normalised to run down or
/// right: its two ends, the turn point, then the cells between (ends excluded).
fn connect(
    rooms: &[Room],
    maze_has: &dyn Fn(usize, i32, i32) -> bool,
    a: usize,
    b: usize,
    dir: Dir,
    rng: &mut XorShift128,
    out: &mut Vec<(i32, i32, Dug)>,
) {
    let (a, b, dir) = match dir {
        Dir::Up => (b, a, Dir::Down),
        Dir::Left => (b, a, Dir::Right),
        _ => (a, b, dir),
    };
    let back = if dir == Dir::Down { Dir::Up } else { Dir::Left };
    let start = end_point(rooms, maze_has, a, dir, rng);
    let end = end_point(rooms, maze_has, b, back, rng);
    let kind = |r: usize| {
        if rooms[r].kind == RoomKind::Normal {
            Dug::Door
        } else {
            Dug::Passage
        }
    };
    out.push((start.0, start.1, kind(a)));
    out.push((end.0, end.1, kind(b)));
    let (turn_start, turn_dir, turn_end) = if dir == Dir::Down {
        let y = rng.range_i32(start.1 + 1, end.1);
        let side = if start.0 < end.0 {
            Dir::Right
        } else {
            Dir::Left
        };
        ((start.0, y), side, (end.0, y))
    } else {
        let x = rng.range_i32(start.0 + 1, end.0);
        let side = if start.1 < end.1 { Dir::Down } else { Dir::Up };
        ((x, start.1), side, (x, end.1))
    };
    let mut walk = |from: (i32, i32), d: Dir, to: (i32, i32), skip_first: bool| {
        let (dx, dy) = d.delta();
        let mut at = from;
        let mut first = true;
        // A corridor is at most a screen long; the bound only guards configs whose turn range
        // is empty (a panic in the original).
        for _ in 0..MAX_CORRIDOR_LEG {
            if at == to {
                break;
            }
            if !(first && skip_first) {
                out.push((at.0, at.1, Dug::Passage));
            }
            first = false;
            at = (at.0 + dx, at.1 + dy);
        }
    };
    walk(start, dir, turn_start, true);
    walk(turn_start, turn_dir, turn_end, false);
    walk(turn_end, dir, end, false);
}

/// The cells of `rect`'s side facing `dir`: without corners for a room's wall
/// (`inclusive`), the whole row or column for a maze.
fn side(rect: Rect, dir: Dir, inclusive: bool) -> Vec<(i32, i32)> {
    let o = i32::from(inclusive);
    match dir {
        Dir::Down => ((rect.x0 + o)..(rect.x1 - o))
            .map(|x| (x, rect.y1 - 1))
            .collect(),
        Dir::Up => ((rect.x0 + o)..(rect.x1 - o))
            .map(|x| (x, rect.y0))
            .collect(),
        Dir::Left => ((rect.y0 + o)..(rect.y1 - o))
            .map(|y| (rect.x0, y))
            .collect(),
        _ => ((rect.y0 + o)..(rect.y1 - o))
            .map(|y| (rect.x1 - 1, y))
            .collect(),
    }
}

/// Where a corridor leaves room `r` towards `dir`: a uniform cell of a normal room's wall
/// (`choose`, a `usize` draw); in a maze, a uniform maze cell of the facing side, the side
/// moving inwards while it has none; a gone room's junction (no draw).
fn end_point(
    rooms: &[Room],
    maze_has: &dyn Fn(usize, i32, i32) -> bool,
    r: usize,
    dir: Dir,
    rng: &mut XorShift128,
) -> (i32, i32) {
    let room = &rooms[r];
    match room.kind {
        RoomKind::Gone => (room.rect.x0, room.rect.y0),
        RoomKind::Normal => {
            let cells = side(room.rect, dir, true);
            let k = rng.below_usize(cells.len());
            cells
                .get(k)
                .copied()
                .unwrap_or((room.rect.x0, room.rect.y0))
        }
        RoomKind::Maze => {
            let mut rect = room.rect;
            while rect.x0 < rect.x1 && rect.y0 < rect.y1 {
                let cells: Vec<_> = side(rect, dir, false)
                    .into_iter()
                    .filter(|&(x, y)| maze_has(r, x, y))
                    .collect();
                if !cells.is_empty() {
                    return cells[rng.below_usize(cells.len())];
                }
                // The original widens Up and Left sides outwards, but the maze's top-left
                // cell is always dug, so they never come up empty.
                match dir {
                    Dir::Down => rect.y1 -= 1,
                    Dir::Right => rect.x1 -= 1,
                    _ => break,
                }
            }
            (room.rect.x0, room.rect.y0)
        }
    }
}
