//! The original's dungeon generator (Rogue-Gym v0.0.2), draw for draw, for
//! `"seeding": "original"`. It writes the same [`Floor`] as ours, so the rules never know
//! which generator made a floor. Facts taken from the original (and checked against its
//! dungeon oracle in `../shared/reference/original-dungeons/`):
//! - two raw-seeded streams, continued across floors: the dungeon stream draws the layout,
//!   the gold cells, the stairs and the player's start (and later each search next to a
//!   hidden cell); the item stream draws gold amounts and, once, the starting kit;
//! - a floor draws in this order: gone rooms, each slot's room, each maze cell's hidden
//!   roll, the corridors (ends, turn, then a hidden/secret roll per registered cell, cells
//!   written twice rolling twice), a cell per real room for gold, the stairs, the start;
//! - the start is any cell free of characters, so it may hold gold or the stairs.
//!
//! Kept from our rules: the amulet (the original has none) is placed after the stairs from
//! `amulet_level` on; monsters are placed by our rules after the player (the original's
//! monster placement is not reproduced).

mod cells;
mod passages;
mod rooms;

use self::cells::{FreeCells, Occupant};
use self::passages::Dug;
use super::floor::{Floor, RoomKind, Surface, flag};
use super::mark_slots;
use crate::config::{GameConfig, InitItem};
use crate::geometry::Rect;
use crate::rng::xorshift::XorShift128;

/// The original's random streams of one game, continued from floor to floor.
#[derive(Debug, Clone)]
pub struct OriginalStreams {
    /// Layout, gold cells, stairs, starts, searches.
    pub(crate) dungeon: XorShift128,
    /// Gold amounts and the starting kit.
    items: XorShift128,
}

impl OriginalStreams {
    /// The streams of `seed`, before floor 1.
    pub fn new(seed: u64) -> Self {
        OriginalStreams {
            dungeon: XorShift128::from_seed(seed),
            items: XorShift128::from_seed(seed),
        }
    }

    /// The item-stream draws of the starting kit, which the original makes after floor 1 is
    /// generated: one count roll per starting weapon, in the width of its table's
    /// `init_num` range (armour and the rest draw nothing).
    pub fn draw_starting_kit(&mut self, cfg: &GameConfig) {
        for item in &cfg.player.init_items {
            // Validation guarantees the weapon is in the table.
            if let InitItem::Weapon(w) = item
                && let Some((lo, hi)) = cfg.item.weapon.count_range_of(&w.name)
            {
                self.items.below_u32(hi.saturating_sub(lo));
            }
        }
    }
}

/// The two rolls a registered cell can make.
#[derive(Debug, Clone, Copy)]
enum Attr {
    /// A passage or maze cell: hidden?
    Passage,
    /// A door: secret ("locked")?
    Door,
}

/// The original's `gen_attr`: `rand[0, dark_level) < level`, and only then
/// `one_in(hidden_passage_rate_inv)` or `one_in(locked_door_rate_inv)`.
fn cell_attr(attr: Attr, cfg: &GameConfig, level: u32, rng: &mut XorShift128) -> bool {
    let d = &cfg.dungeon;
    let inv = match attr {
        Attr::Passage => d.hidden_passage_rate_inv,
        Attr::Door => d.locked_door_rate_inv,
    };
    rng.below_u32(d.dark_level) < level && rng.one_in(inv)
}

/// Generates floor `level` into `floor` from the streams, and returns the player's start.
pub fn generate(
    floor: &mut Floor,
    slots: &[Rect],
    cfg: &GameConfig,
    level: u32,
    streams: &mut OriginalStreams,
) -> usize {
    let rng = &mut streams.dungeon;
    floor.clear(cfg.width, cfg.height);
    let planned = rooms::plan_rooms(floor, slots, cfg, level, rng);
    rooms::draw_rooms(floor, &planned, cfg, level, rng);
    let mut free = FreeCells::default();
    for p in &planned {
        free.push(match p.room.kind {
            RoomKind::Gone => None,
            RoomKind::Maze => Some(p.maze.clone()),
            RoomKind::Normal => {
                let r = p.room.rect;
                let inner = Rect {
                    x0: r.x0 + 1,
                    y0: r.y0 + 1,
                    x1: r.x1 - 1,
                    y1: r.y1 - 1,
                };
                let cells = (inner.y0..inner.y1)
                    .flat_map(|y| (inner.x0..inner.x1).map(move |x| (x, y)))
                    .map(|(x, y)| floor.idx(x, y))
                    .collect();
                Some(cells)
            }
        });
        floor.rooms.push(p.room);
    }
    mark_slots(floor);
    // Corridors, then each registered cell's roll in order: a hidden passage or a secret
    // door keeps the surface it had; a later registration re-rolls the cell.
    let maze_has = |r: usize, x: i32, y: i32| {
        planned[r].room.rect.contains(x, y)
            && planned[r].maze.binary_search(&floor.idx(x, y)).is_ok()
    };
    let dug = passages::dig(&floor.rooms, cfg, &maze_has, rng);
    for (x, y, kind) in dug {
        let i = floor.idx(x, y);
        let (attr, surface, hidden_bit) = match kind {
            Dug::Door => (Attr::Door, Surface::Door, flag::LOCKED),
            Dug::Passage => (Attr::Passage, Surface::Passage, flag::HIDDEN),
        };
        if kind == Dug::Door {
            floor.flags[i] |= flag::DOOR;
        }
        floor.flags[i] &= !(flag::HIDDEN | flag::LOCKED | flag::DARK);
        if cell_attr(attr, cfg, level, rng) {
            floor.flags[i] |= hidden_bit;
        } else {
            floor.surface[i] = surface;
        }
    }
    // Gold: a cell per real room (dungeon stream), the roll and amount from the item stream.
    let g = &cfg.item.gold;
    for r in 0..floor.rooms.len() {
        let Some(cell) = free.pick_in_room(r, Occupant::Object, rng) else {
            continue;
        };
        if !streams.items.one_in(g.rate_inv) {
            continue;
        }
        let span = g.base.saturating_add(g.per_level.saturating_mul(level));
        let amount = streams.items.below_u32(span).saturating_add(g.minimum);
        if amount > 0 {
            free.fill(r, cell, Occupant::Object);
            floor.gold[cell] = amount;
            floor.rooms[r].has_gold = true;
        }
    }
    let mut place = |floor: &mut Floor, free: &mut FreeCells, who| {
        let cell = free.pick(who, rng)?;
        if let Some(r) = floor.room_at(cell) {
            free.fill(r, cell, who);
        }
        Some(cell)
    };
    if let Some(cell) = place(floor, &mut free, Occupant::Object) {
        floor.surface[cell] = Surface::Stair;
        floor.stairs = cell;
    }
    if level >= cfg.dungeon.amulet_level {
        floor.amulet = place(floor, &mut free, Occupant::Object);
    }
    place(floor, &mut free, Occupant::Character).unwrap_or(floor.stairs)
}
