//! Room slots, gone rooms, normal rooms and mazes (docs/rules.md §2.1-2.3).

use super::floor::{Floor, Room, RoomKind, Surface, flag};
use crate::config::GameConfig;
use crate::geometry::{Dir, Rect};
use crate::rng::GameRng;

/// The room slots of a config, in id order (`i + j * nx`), with the per-row adjustments.
pub fn slots(cfg: &GameConfig) -> Vec<Rect> {
    let (nx, ny) = (cfg.dungeon.room_num_x, cfg.dungeon.room_num_y);
    let (sw, sh) = cfg.slot_size();
    let mut out = Vec::with_capacity((nx * ny) as usize);
    for j in 0..ny {
        for i in 0..nx {
            let x0 = i * sw;
            let (mut y0, mut h) = (j * sh, sh);
            if j == 0 {
                y0 = 1;
                h -= 1;
            }
            if y0 + h >= cfg.height {
                h = cfg.height - 1 - y0;
            }
            out.push(Rect {
                x0,
                y0,
                x1: x0 + sw,
                y1: y0 + h,
            });
        }
    }
    out
}

/// Which slots are gone: `k = rand[0, max_empty_rooms]` capped at n-1, chosen without
/// replacement.
pub fn choose_gone(rng: &mut GameRng, n: usize, max_empty: u32, gone: &mut Vec<bool>) {
    gone.clear();
    gone.resize(n, false);
    let k = (rng.below(max_empty.saturating_add(1)) as usize).min(n - 1);
    for picked in 0..k {
        let mut nth = rng.below((n - picked) as u32) as usize;
        for (id, g) in gone.iter_mut().enumerate() {
            let _ = id;
            if !*g {
                if nth == 0 {
                    *g = true;
                    break;
                }
                nth -= 1;
            }
        }
    }
}

/// Builds the room of one slot on the floor.
pub fn build_room(
    floor: &mut Floor,
    rng: &mut GameRng,
    cfg: &GameConfig,
    level: u32,
    slot: Rect,
    gone: bool,
    maze_stack: &mut Vec<(i32, i32)>,
) -> Room {
    let d = &cfg.dungeon;
    if gone {
        let x = slot.x0 + rng.range(1, slot.w() - 1);
        let y = slot.y0 + rng.range(1, slot.h() - 1);
        return gone_room(slot, x, y);
    }
    let dark = rng.below(d.dark_level) < level;
    if dark && rng.one_in(d.maze_rate_inv) {
        let rect = maze_rect(slot);
        carve_maze(floor, rng, cfg, level, rect, maze_stack);
        return Room::new(RoomKind::Maze, slot, rect, true);
    }
    let sx = rng.range(d.min_room_size.x, slot.w());
    let sy = rng.range(d.min_room_size.y, slot.h());
    let ox = rng.range(0, slot.w() - sx);
    let oy = rng.range(0, slot.h() - sy);
    let rect = Rect {
        x0: slot.x0 + ox,
        y0: slot.y0 + oy,
        x1: slot.x0 + ox + sx,
        y1: slot.y0 + oy + sy,
    };
    draw_normal_room(floor, rect, dark);
    Room::new(RoomKind::Normal, slot, rect, dark)
}

/// A gone room of `slot`: a single junction cell at `(x, y)`, dark.
pub(super) fn gone_room(slot: Rect, x: i32, y: i32) -> Room {
    let junction = Rect {
        x0: x,
        y0: y,
        x1: x + 1,
        y1: y + 1,
    };
    Room::new(RoomKind::Gone, slot, junction, true)
}

/// The rectangle a maze fills in `slot`: all of it but the last column and row.
pub(super) fn maze_rect(slot: Rect) -> Rect {
    Rect {
        x0: slot.x0,
        y0: slot.y0,
        x1: slot.x1 - 1,
        y1: slot.y1 - 1,
    }
}

/// Draws a normal room: `-` on the top and bottom rows (corners included), `|` on the side
/// columns, floor inside (flagged dark in a dark room).
pub(super) fn draw_normal_room(floor: &mut Floor, rect: Rect, dark: bool) {
    for y in rect.y0..rect.y1 {
        for x in rect.x0..rect.x1 {
            let i = floor.idx(x, y);
            if y == rect.y0 || y == rect.y1 - 1 {
                floor.surface[i] = Surface::WallH;
            } else if x == rect.x0 || x == rect.x1 - 1 {
                floor.surface[i] = Surface::WallV;
            } else {
                floor.surface[i] = Surface::Floor;
                if dark {
                    floor.flags[i] |= flag::DARK;
                }
            }
        }
    }
}

/// Recursive back-tracker on a step-2 lattice from the top-left cell (iterative, with a
/// reused stack). Carved cells are passages, each rolling the hidden-passage rule.
fn carve_maze(
    floor: &mut Floor,
    rng: &mut GameRng,
    cfg: &GameConfig,
    level: u32,
    rect: Rect,
    stack: &mut Vec<(i32, i32)>,
) {
    stack.clear();
    let carve = |floor: &mut Floor, rng: &mut GameRng, x: i32, y: i32| {
        let i = floor.idx(x, y);
        floor.flags[i] |= flag::REGISTERED;
        if rng.below(cfg.dungeon.dark_level) < level
            && rng.one_in(cfg.dungeon.hidden_passage_rate_inv)
        {
            floor.flags[i] |= flag::HIDDEN;
        } else {
            floor.surface[i] = Surface::Passage;
        }
    };
    let carved =
        |floor: &Floor, x: i32, y: i32| floor.flags[floor.idx(x, y)] & flag::REGISTERED != 0;
    carve(floor, rng, rect.x0, rect.y0);
    stack.push((rect.x0, rect.y0));
    while let Some(&(x, y)) = stack.last() {
        let mut chosen = None;
        let mut count = 0u32;
        for dir in [Dir::Up, Dir::Down, Dir::Left, Dir::Right] {
            let (dx, dy) = dir.delta();
            let (nx, ny) = (x + 2 * dx, y + 2 * dy);
            if rect.contains(nx, ny) && !carved(floor, nx, ny) {
                count += 1;
                if rng.below(count) == 0 {
                    chosen = Some((dx, dy));
                }
            }
        }
        match chosen {
            Some((dx, dy)) => {
                carve(floor, rng, x + dx, y + dy);
                carve(floor, rng, x + 2 * dx, y + 2 * dy);
                stack.push((x + 2 * dx, y + 2 * dy));
            }
            None => {
                stack.pop();
            }
        }
    }
}
