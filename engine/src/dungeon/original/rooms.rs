//! The original's rooms, draw for draw: which slots are gone, then per slot the dark roll,
//! the maze roll and the maze's digging or the room's size and position.

use super::super::floor::{Floor, Room, RoomKind, Surface, flag};
use super::super::rooms::{draw_normal_room, gone_room, maze_rect};
use super::{Attr, cell_attr};
use crate::config::GameConfig;
use crate::geometry::{Dir, Rect};
use crate::rng::xorshift::XorShift128;

/// A room as the original generates it, before it is drawn.
pub(super) struct Planned {
    /// The room.
    pub room: Room,
    /// A maze's cells in row order (empty for other kinds).
    pub maze: Vec<usize>,
}

/// Which slots are gone: `rand[0, max_empty_rooms]` (capped at n - 1) as a u32, then that
/// many picks without replacement, each the n-th remaining slot with n drawn as a `usize`.
fn gone_slots(rng: &mut XorShift128, n: usize, max_empty: u32) -> Vec<bool> {
    let mut k = rng.below_u32(max_empty.saturating_add(1)) as usize;
    if k >= n {
        k = n.saturating_sub(1);
    }
    let mut remaining: Vec<usize> = (0..n).collect();
    let mut gone = vec![false; n];
    for _ in 0..k {
        let pick = remaining.remove(rng.below_usize(remaining.len()));
        gone[pick] = true;
    }
    gone
}

/// Plans every slot's room, in slot order.
pub(super) fn plan_rooms(
    floor: &Floor,
    slots: &[Rect],
    cfg: &GameConfig,
    level: u32,
    rng: &mut XorShift128,
) -> Vec<Planned> {
    let d = &cfg.dungeon;
    let gone = gone_slots(rng, slots.len(), d.max_empty_rooms);
    let mut planned = Vec::with_capacity(slots.len());
    for (id, &slot) in slots.iter().enumerate() {
        if gone[id] {
            let x = slot.x0 + rng.range_i32(1, slot.w() - 1);
            let y = slot.y0 + rng.range_i32(1, slot.h() - 1);
            planned.push(Planned {
                room: gone_room(slot, x, y),
                maze: Vec::new(),
            });
            continue;
        }
        let dark = rng.below_u32(d.dark_level) < level;
        if dark && rng.one_in(d.maze_rate_inv) {
            let rect = maze_rect(slot);
            let maze = dig_maze(floor, rect, rng);
            planned.push(Planned {
                room: Room::new(RoomKind::Maze, slot, rect, true),
                maze,
            });
            continue;
        }
        let w = rng.range_i32(d.min_room_size.x, slot.w());
        let h = rng.range_i32(d.min_room_size.y, slot.h());
        let x0 = slot.x0 + rng.range_i32(0, slot.w() - w);
        let y0 = slot.y0 + rng.range_i32(0, slot.h() - h);
        let rect = Rect {
            x0,
            y0,
            x1: x0 + w,
            y1: y0 + h,
        };
        planned.push(Planned {
            room: Room::new(RoomKind::Normal, slot, rect, dark),
            maze: Vec::new(),
        });
    }
    planned
}

/// The original's maze: a depth-first dig on the step-2 lattice from the top-left cell.
/// At each cell, every open direction (Up, Down, Left, Right order) draws `one_in(k + 1)`
/// for its rank k, and the last that comes out true is dug. Returns the cells in row order.
fn dig_maze(floor: &Floor, rect: Rect, rng: &mut XorShift128) -> Vec<usize> {
    let local = |x: i32, y: i32| ((y - rect.y0) * rect.w() + (x - rect.x0)) as usize;
    let mut used = vec![false; (rect.w() * rect.h()).max(0) as usize];
    used[local(rect.x0, rect.y0)] = true;
    let mut stack = vec![(rect.x0, rect.y0)];
    while let Some(&(x, y)) = stack.last() {
        let mut rank = 0u32;
        let mut chosen = None;
        for dir in [Dir::Up, Dir::Down, Dir::Left, Dir::Right] {
            let (dx, dy) = dir.delta();
            let (nx, ny) = (x + 2 * dx, y + 2 * dy);
            if rect.contains(nx, ny) && !used[local(nx, ny)] {
                rank += 1;
                if rng.one_in(rank) {
                    chosen = Some((dx, dy));
                }
            }
        }
        let Some((dx, dy)) = chosen else {
            stack.pop();
            continue;
        };
        used[local(x + dx, y + dy)] = true;
        used[local(x + 2 * dx, y + 2 * dy)] = true;
        stack.push((x + 2 * dx, y + 2 * dy));
    }
    let mut cells = Vec::new();
    for y in rect.y0..rect.y1 {
        for x in rect.x0..rect.x1 {
            if used[local(x, y)] {
                cells.push(floor.idx(x, y));
            }
        }
    }
    cells
}

/// Draws the planned rooms in slot order: walls and floor as they are, and each maze cell a
/// passage with its hidden roll.
pub(super) fn draw_rooms(
    floor: &mut Floor,
    planned: &[Planned],
    cfg: &GameConfig,
    level: u32,
    rng: &mut XorShift128,
) {
    for p in planned {
        match p.room.kind {
            RoomKind::Normal => draw_normal_room(floor, p.room.rect, p.room.dark),
            RoomKind::Maze => {
                for &i in &p.maze {
                    floor.surface[i] = Surface::Passage;
                    if cell_attr(Attr::Passage, cfg, level, rng) {
                        floor.flags[i] |= flag::HIDDEN;
                    }
                }
            }
            RoomKind::Gone => {}
        }
    }
}
