//! Dungeon generation, "rogue" style (docs/rules.md §2): slots, rooms, passages, hidden
//! features, gold, stairs and the amulet. A floor depends only on (config, seed, level).

pub mod floor;
pub mod original;
mod passages;
mod rooms;

pub use floor::{Floor, RoomKind, Surface, flag};

use crate::config::GameConfig;
use crate::geometry::Rect;
use crate::rng::{GameRng, Stream};

/// Reusable buffers for generation.
#[derive(Debug, Default, Clone)]
pub struct Generator {
    slots: Vec<Rect>,
    gone: Vec<bool>,
    edges: Vec<u8>,
    order: Vec<(usize, usize)>,
    stack: Vec<(i32, i32)>,
    cells: Vec<u32>,
}

impl Generator {
    /// A generator for `cfg` (computes the slots once).
    pub fn new(cfg: &GameConfig) -> Self {
        Generator {
            slots: rooms::slots(cfg),
            ..Default::default()
        }
    }

    /// The room slots, in id order.
    pub fn slots(&self) -> &[Rect] {
        &self.slots
    }

    /// Generates floor `level` of `seed` into `floor`. Returns the dungeon stream, left where
    /// generation stopped, for the caller's placements (player).
    pub fn generate(
        &mut self,
        floor: &mut Floor,
        cfg: &GameConfig,
        seed: u64,
        level: u32,
    ) -> GameRng {
        let mut rng = GameRng::new(seed, Stream::Dungeon, u64::from(level));
        let mut item_rng = GameRng::new(seed, Stream::Items, u64::from(level));
        floor.clear(cfg.width, cfg.height);
        let n = self.slots.len();
        rooms::choose_gone(&mut rng, n, cfg.dungeon.max_empty_rooms, &mut self.gone);
        for id in 0..n {
            let slot = self.slots[id];
            let room = rooms::build_room(
                floor,
                &mut rng,
                cfg,
                level,
                slot,
                self.gone[id],
                &mut self.stack,
            );
            floor.rooms.push(room);
        }
        mark_slots(floor);
        passages::choose_edges(&mut rng, cfg, &mut self.edges, &mut self.order);
        for k in 0..self.order.len() {
            let (a, b) = self.order[k];
            let rooms = std::mem::take(&mut floor.rooms);
            passages::connect(floor, &mut rng, cfg, level, &rooms, a, b);
            floor.rooms = rooms;
        }
        // Gold: one candidate cell per real room (dungeon stream), the roll and amount from the
        // item stream.
        let g = &cfg.item.gold;
        for id in 0..n {
            if floor.rooms[id].kind == RoomKind::Gone {
                continue;
            }
            if let Some(cell) = self.random_empty_cell(floor, &mut rng, id)
                && item_rng.one_in(g.rate_inv)
            {
                let span = g.base.saturating_add(g.per_level.saturating_mul(level));
                floor.gold[cell] = g.minimum.saturating_add(item_rng.below(span));
                floor.rooms[id].has_gold = floor.gold[cell] > 0;
            }
        }
        // Stairs, then the amulet (from amulet_level on): uniform room, then uniform cell.
        // Fallback (tiny rooms all taken by gold): any floor or passage cell, gold allowed.
        let stairs = self.random_room_cell(floor, &mut rng).or_else(|| {
            self.cells.clear();
            let cells = (0..floor.surface.len())
                .filter(|&i| matches!(floor.surface[i], Surface::Floor | Surface::Passage));
            self.cells.extend(cells.map(|i| i as u32));
            let n = self.cells.len() as u32;
            (n > 0).then(|| self.cells[rng.below(n) as usize] as usize)
        });
        if let Some(cell) = stairs {
            floor.surface[cell] = Surface::Stair;
            floor.stairs = cell;
        }
        if level >= cfg.dungeon.amulet_level {
            floor.amulet = self.random_room_cell(floor, &mut rng);
        }
        if !cfg.hide_dungeon {
            let (a, b) = (floor.w as usize, ((floor.h - 1) * floor.w) as usize);
            for f in &mut floor.flags[a..b] {
                *f |= flag::VISIBLE;
            }
        }
        rng
    }

    /// A uniformly chosen empty cell of room `id` (its rectangle), if any.
    pub fn random_empty_cell(
        &mut self,
        floor: &Floor,
        rng: &mut GameRng,
        id: usize,
    ) -> Option<usize> {
        self.random_cell_where(floor, rng, id, |f, i| f.is_empty_cell(i))
    }

    /// A uniformly chosen cell of room `id` (its rectangle) that passes `ok`, if any.
    pub fn random_cell_where(
        &mut self,
        floor: &Floor,
        rng: &mut GameRng,
        id: usize,
        ok: impl Fn(&Floor, usize) -> bool,
    ) -> Option<usize> {
        self.collect_where(floor, id, ok);
        if self.cells.is_empty() {
            return None;
        }
        Some(self.cells[rng.below(self.cells.len() as u32) as usize] as usize)
    }

    /// A uniform real room with an empty cell, then a uniform empty cell in it.
    pub fn random_room_cell(&mut self, floor: &Floor, rng: &mut GameRng) -> Option<usize> {
        self.random_room_cell_where(floor, rng, |_| true)
    }

    /// Like [`Generator::random_room_cell`] with an extra filter on cells.
    pub fn random_room_cell_where(
        &mut self,
        floor: &Floor,
        rng: &mut GameRng,
        ok: impl Fn(usize) -> bool,
    ) -> Option<usize> {
        let n = floor.rooms.len();
        let mut candidates: u64 = 0; // bit set of rooms with a free cell (n <= 255 => use a loop)
        let mut count = 0u32;
        let mut ids = [0u8; 256];
        for id in 0..n {
            if floor.rooms[id].kind == RoomKind::Gone {
                continue;
            }
            self.collect_empty(floor, id);
            if self.cells.iter().any(|&c| ok(c as usize)) {
                ids[count as usize] = id as u8;
                count += 1;
                candidates += 1;
            }
        }
        if candidates == 0 {
            return None;
        }
        let id = ids[rng.below(count) as usize] as usize;
        self.collect_empty(floor, id);
        self.cells.retain(|&c| ok(c as usize));
        Some(self.cells[rng.below(self.cells.len() as u32) as usize] as usize)
    }

    fn collect_empty(&mut self, floor: &Floor, id: usize) {
        self.collect_where(floor, id, |f, i| f.is_empty_cell(i));
    }

    fn collect_where(&mut self, floor: &Floor, id: usize, ok: impl Fn(&Floor, usize) -> bool) {
        self.cells.clear();
        let r = floor.rooms[id].rect;
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                let i = floor.idx(x, y);
                if ok(floor, i) {
                    self.cells.push(i as u32);
                }
            }
        }
    }
}

/// Fills the per-cell slot ids and zones (slot * 2, + 1 inside the room) from the rooms.
pub(crate) fn mark_slots(floor: &mut Floor) {
    for id in 0..floor.rooms.len() {
        let room = floor.rooms[id];
        let slot = room.slot;
        for y in slot.y0..slot.y1 {
            for x in slot.x0..slot.x1 {
                let i = floor.idx(x, y);
                floor.slot_of[i] = id as u8;
                let inside = room.kind != RoomKind::Gone && room.rect.contains(x, y);
                floor.zone[i] = (id * 2) as u16 + u16::from(inside);
            }
        }
    }
}
