//! Connecting rooms: a uniform random spanning tree of the slot grid (Aldous-Broder random
//! walk, so every spanning tree is possible: the original's star bias is fixed), extra edges,
//! and L/Z-shaped passages between doors (docs/rules.md §2.4-2.5).

use super::floor::{Floor, Room, RoomKind, Surface, flag};
use crate::config::GameConfig;
use crate::geometry::{Dir, Rect};
use crate::rng::GameRng;

/// Direction bits of an adjacency mask.
const UP: u8 = 1;
const DOWN: u8 = 2;
const LEFT: u8 = 4;
const RIGHT: u8 = 8;

/// The grid neighbours of slot `id` as (neighbour id, direction bit), in ascending id order.
fn neighbours(id: usize, nx: usize, ny: usize) -> impl Iterator<Item = (usize, u8)> {
    let (i, j) = (id % nx, id / nx);
    [
        (j > 0).then(|| (id - nx, UP)),
        (i > 0).then(|| (id - 1, LEFT)),
        (i + 1 < nx).then(|| (id + 1, RIGHT)),
        (j + 1 < ny).then(|| (id + nx, DOWN)),
    ]
    .into_iter()
    .flatten()
}

/// Chooses the room graph's edges: a spanning tree plus extra edges. Returns the number of
/// edges; `edges` gets one direction mask per room.
pub fn choose_edges(
    rng: &mut GameRng,
    cfg: &GameConfig,
    edges: &mut Vec<u8>,
    order: &mut Vec<(usize, usize)>,
) {
    let nx = cfg.dungeon.room_num_x as usize;
    let ny = cfg.dungeon.room_num_y as usize;
    let n = nx * ny;
    edges.clear();
    edges.resize(n, 0);
    order.clear();
    // Aldous-Broder: walk randomly; the first entry into a room adds the edge used.
    let mut in_tree = vec![false; n];
    let mut cur = rng.below(n as u32) as usize;
    in_tree[cur] = true;
    let mut remaining = n - 1;
    while remaining > 0 {
        let count = neighbours(cur, nx, ny).count() as u32;
        let pick = rng.below(count) as usize;
        let Some((next, _)) = neighbours(cur, nx, ny).nth(pick) else {
            break;
        };
        if !in_tree[next] {
            in_tree[next] = true;
            remaining -= 1;
            link(edges, order, cur, next, nx);
        }
        cur = next;
    }
    // Extra edges: rand[0, max_extra_edges) attempts (0 attempts when max_extra_edges is 0).
    let attempts = rng.below(cfg.dungeon.max_extra_edges);
    for _ in 0..attempts {
        let r1 = rng.below(n as u32) as usize;
        let mut chosen = None;
        let mut count = 0;
        for (nb, bit) in neighbours(r1, nx, ny) {
            if edges[r1] & bit == 0 {
                count += 1;
                if rng.below(count) == 0 {
                    chosen = Some(nb);
                }
            }
        }
        if let Some(nb) = chosen {
            link(edges, order, r1, nb, nx);
        }
    }
}

fn link(edges: &mut [u8], order: &mut Vec<(usize, usize)>, a: usize, b: usize, nx: usize) {
    let (a, b) = (a.min(b), a.max(b));
    if b == a + 1 && a / nx == b / nx {
        edges[a] |= RIGHT;
        edges[b] |= LEFT;
    } else {
        edges[a] |= DOWN;
        edges[b] |= UP;
    }
    order.push((a, b));
}

/// Digs the passage between rooms `a` and `b` (`a` left of or above `b`).
pub fn connect(
    floor: &mut Floor,
    rng: &mut GameRng,
    cfg: &GameConfig,
    level: u32,
    rooms: &[Room],
    a: usize,
    b: usize,
) {
    let nx = cfg.dungeon.room_num_x as usize;
    let horizontal = b == a + 1 && a / nx == b / nx;
    let (da, db) = if horizontal {
        (Dir::Right, Dir::Left)
    } else {
        (Dir::Down, Dir::Up)
    };
    let (sx, sy, sdoor) = endpoint(floor, rng, &rooms[a], da);
    let (ex, ey, edoor) = endpoint(floor, rng, &rooms[b], db);
    register(floor, rng, cfg, level, sx, sy, sdoor);
    // The L/Z path; cells strictly between the endpoints.
    let (mut x, mut y) = (sx, sy);
    if horizontal {
        let tx = rng.range(sx + 1, ex);
        while x < tx {
            x += 1;
            register(floor, rng, cfg, level, x, y, false);
        }
        while y != ey {
            y += (ey - y).signum();
            register(floor, rng, cfg, level, x, y, false);
        }
        while x + 1 < ex {
            x += 1;
            register(floor, rng, cfg, level, x, y, false);
        }
    } else {
        let ty = rng.range(sy + 1, ey);
        while y < ty {
            y += 1;
            register(floor, rng, cfg, level, x, y, false);
        }
        while x != ex {
            x += (ex - x).signum();
            register(floor, rng, cfg, level, x, y, false);
        }
        while y + 1 < ey {
            y += 1;
            register(floor, rng, cfg, level, x, y, false);
        }
    }
    register(floor, rng, cfg, level, ex, ey, edoor);
}

/// The endpoint of a passage on `room`'s side facing `dir`: `(x, y, is_door)`.
fn endpoint(floor: &Floor, rng: &mut GameRng, room: &Room, dir: Dir) -> (i32, i32, bool) {
    let r = room.rect;
    match room.kind {
        RoomKind::Gone => (r.x0, r.y0, false),
        RoomKind::Normal => {
            let (x, y) = match dir {
                Dir::Down => (rng.range(r.x0 + 1, r.x1 - 1), r.y1 - 1),
                Dir::Up => (rng.range(r.x0 + 1, r.x1 - 1), r.y0),
                Dir::Right => (r.x1 - 1, rng.range(r.y0 + 1, r.y1 - 1)),
                _ => (r.x0, rng.range(r.y0 + 1, r.y1 - 1)),
            };
            (x, y, true)
        }
        RoomKind::Maze => {
            // A carved cell on that side; move inward until the line has one.
            let mut side = r;
            loop {
                let line = match dir {
                    Dir::Down => Rect {
                        y0: side.y1 - 1,
                        ..side
                    },
                    Dir::Up => Rect {
                        y1: side.y0 + 1,
                        ..side
                    },
                    Dir::Right => Rect {
                        x0: side.x1 - 1,
                        ..side
                    },
                    _ => Rect {
                        x1: side.x0 + 1,
                        ..side
                    },
                };
                let carved = |x: i32, y: i32| floor.flags[floor.idx(x, y)] & flag::REGISTERED != 0;
                let count = (line.y0..line.y1)
                    .flat_map(|y| (line.x0..line.x1).map(move |x| (x, y)))
                    .filter(|&(x, y)| carved(x, y))
                    .count();
                if count > 0 {
                    let nth = rng.below(count as u32) as usize;
                    if let Some((x, y)) = (line.y0..line.y1)
                        .flat_map(|y| (line.x0..line.x1).map(move |x| (x, y)))
                        .filter(|&(x, y)| carved(x, y))
                        .nth(nth)
                    {
                        return (x, y, false);
                    }
                }
                match dir {
                    Dir::Down => side.y1 -= 1,
                    Dir::Up => side.y0 += 1,
                    Dir::Right => side.x1 -= 1,
                    _ => side.x0 += 1,
                }
                if side.w() <= 0 || side.h() <= 0 {
                    // Unreachable: the maze's first cell is always carved.
                    return (r.x0, r.y0, false);
                }
            }
        }
    }
}

/// Registers a passage or door cell: the first registration rolls whether it is hidden; later
/// registrations leave it as it is (no re-hiding).
fn register(
    floor: &mut Floor,
    rng: &mut GameRng,
    cfg: &GameConfig,
    level: u32,
    x: i32,
    y: i32,
    door: bool,
) {
    let i = floor.idx(x, y);
    if floor.flags[i] & flag::REGISTERED != 0 {
        return;
    }
    floor.flags[i] |= flag::REGISTERED;
    let d = &cfg.dungeon;
    let deep = rng.below(d.dark_level) < level;
    if door {
        floor.flags[i] |= flag::DOOR;
        if deep && rng.one_in(d.locked_door_rate_inv) {
            floor.flags[i] |= flag::LOCKED;
        } else {
            floor.surface[i] = Surface::Door;
        }
    } else if deep && rng.one_in(d.hidden_passage_rate_inv) {
        floor.flags[i] |= flag::HIDDEN;
        floor.surface[i] = Surface::Nothing;
    } else {
        floor.surface[i] = Surface::Passage;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Stream;

    /// The edges `choose_edges` picks for `seeds` floors of a 3x3 grid with `max_extra_edges`.
    fn edge_counts(max_extra_edges: u32, seeds: u64) -> Vec<usize> {
        let mut cfg = GameConfig::default();
        cfg.dungeon.max_extra_edges = max_extra_edges;
        let (mut edges, mut order) = (Vec::new(), Vec::new());
        (0..seeds)
            .map(|s| {
                let mut rng = GameRng::new(s, Stream::Dungeon, 1);
                choose_edges(&mut rng, &cfg, &mut edges, &mut order);
                order.len()
            })
            .collect()
    }

    #[test]
    fn zero_extra_edges_means_a_spanning_tree_and_nothing_more() {
        // 9 rooms: a spanning tree has 8 edges.
        assert!(edge_counts(0, 200).iter().all(|&n| n == 8));
        // The default (5) adds some on some floors, so the count above is not a tautology.
        assert!(edge_counts(5, 200).iter().any(|&n| n > 8));
    }
}
