//! What the player sees (docs/rules.md §4): lit rooms light up on entry, dark rooms show the
//! 3x3 around the player, corridors are revealed orthogonally, seen cells are remembered.
//! Fixes: leaving a dark room no longer blanks its stairs, and `hide_dungeon: false` never
//! blanks anything.

use crate::config::MEAN;
use crate::dungeon::{RoomKind, Surface, flag};
use crate::game::Game;
use crate::geometry::Dir;

impl Game {
    /// Makes a cell visible and remembered.
    pub(crate) fn reveal(&mut self, i: usize) {
        self.floor.flags[i] |= flag::VISIBLE | flag::DRAWN;
        self.touch(i);
    }

    /// Reveals a cell unless it is a hidden passage.
    fn approach(&mut self, i: usize) {
        if self.floor.flags[i] & flag::HIDDEN == 0 {
            self.reveal(i);
        }
    }

    /// The player enters cell `pos` (`initial`: placed on a new floor).
    pub(crate) fn player_in(&mut self, pos: usize, initial: bool) {
        if (initial || self.floor.flags[pos] & flag::DOOR != 0)
            && let Some(r) = self.floor.room_at(pos)
        {
            let room = self.floor.rooms[r];
            if !room.visited {
                self.floor.rooms[r].visited = true;
                if room.is_lit_normal() {
                    for y in room.rect.y0..room.rect.y1 {
                        for x in room.rect.x0..room.rect.x1 {
                            let i = self.floor.idx(x, y);
                            self.reveal(i);
                        }
                    }
                }
            }
            self.wake_mean_enemies(r);
        }
        self.floor.visited[pos] = 1;
        let (x, y) = self.floor.xy(pos);
        self.approach(pos);
        for dir in Dir::ALL {
            let (dx, dy) = dir.delta();
            let (nx, ny) = (x + dx, y + dy);
            if !self.floor.in_area(nx, ny) {
                continue;
            }
            let i = self.floor.idx(nx, ny);
            if dir.is_diagonal() && self.floor.surface[i] == Surface::Passage {
                continue;
            }
            self.approach(i);
        }
    }

    /// The player leaves cell `pos`: dark floor around it goes out of sight.
    pub(crate) fn player_out(&mut self, pos: usize) {
        if !self.cfg.hide_dungeon {
            return;
        }
        if self.floor.flags[pos] & flag::DOOR != 0
            && let Some(r) = self.floor.room_at(pos)
        {
            let room = self.floor.rooms[r];
            if room.visited && room.dark && room.kind == RoomKind::Normal {
                let rect = room.rect;
                for y in rect.y0 + 1..rect.y1 - 1 {
                    for x in rect.x0 + 1..rect.x1 - 1 {
                        let i = self.floor.idx(x, y);
                        self.hide_dark_floor(i);
                    }
                }
            }
        }
        let (x, y) = self.floor.xy(pos);
        for (dx, dy) in [
            (-1, -1),
            (0, -1),
            (1, -1),
            (-1, 0),
            (0, 0),
            (1, 0),
            (-1, 1),
            (0, 1),
            (1, 1),
        ] {
            let (nx, ny) = (x + dx, y + dy);
            if self.floor.in_area(nx, ny) {
                let i = self.floor.idx(nx, ny);
                self.hide_dark_floor(i);
            }
        }
    }

    fn hide_dark_floor(&mut self, i: usize) {
        let f = self.floor.flags[i];
        if self.floor.surface[i] == Surface::Floor && f & flag::DARK != 0 && f & flag::VISIBLE != 0
        {
            self.floor.flags[i] &= !flag::VISIBLE;
            self.touch(i);
        }
    }

    /// Wakes every MEAN monster in room slot `r`.
    fn wake_mean_enemies(&mut self, r: usize) {
        for k in 0..self.enemies.len() {
            let e = self.enemies[k];
            if e.alive
                && !e.awake
                && self.floor.slot_of[e.pos] as usize == r
                && self.kinds[e.kind as usize].attr & MEAN != 0
            {
                self.enemies[k].awake = true;
            }
        }
    }
}
