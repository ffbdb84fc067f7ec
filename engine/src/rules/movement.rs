//! Moving, picking up, searching (docs/rules.md §3).

use crate::dungeon::{Surface, flag};
use crate::game::Game;
use crate::geometry::Dir;

impl Game {
    /// The cell reached from `from` in `dir`, if the move is legal: the target is walkable
    /// (found passages and doors only) and a diagonal move needs both orthogonal cells
    /// walkable (no corner cutting, no diagonal step through a door). Monsters use the same
    /// rule.
    pub(crate) fn can_move(&self, from: usize, dir: Dir) -> Option<usize> {
        let f = &self.floor;
        let (x, y) = f.xy(from);
        let (dx, dy) = dir.delta();
        let (nx, ny) = (x + dx, y + dy);
        if !f.in_area(nx, ny) {
            return None;
        }
        let t = f.idx(nx, ny);
        if !f.surface[t].walkable() {
            return None;
        }
        if dx != 0
            && dy != 0
            && !(f.surface[f.idx(nx, y)].walkable() && f.surface[f.idx(x, ny)].walkable())
        {
            return None;
        }
        Some(t)
    }

    /// The player tries to move: attack a monster there, or move and pick up.
    pub(crate) fn player_move(&mut self, dir: Dir) {
        // A hidden cell stops the player even where it shows (a maze cell rolled hidden, a
        // passage re-rolled hidden under `"seeding": "original"`), as in the original.
        let target = self
            .can_move(self.player.pos, dir)
            .filter(|&t| self.floor.flags[t] & (flag::HIDDEN | flag::LOCKED) == 0);
        let Some(t) = target else {
            self.set_message("You can't move there");
            return;
        };
        let e = self.enemy_at[t];
        if e != 0 {
            self.player_attack(e as usize - 1);
            return;
        }
        let old = self.player.pos;
        self.player_out(old);
        self.player.pos = t;
        self.touch(old);
        self.touch(t);
        self.player_in(t, false);
        self.pick_up(t);
    }

    /// Picks up what lies on cell `i`: gold (reward) or the amulet (win).
    fn pick_up(&mut self, i: usize) {
        let g = self.floor.gold[i];
        if g > 0 {
            self.floor.gold[i] = 0;
            self.player.gold = self.player.gold.saturating_add(g);
            self.reward += g as f32;
            self.touch(i);
            if !self.message.is_empty() {
                self.message.clear();
            }
            use std::fmt::Write;
            let _ = write!(self.message, "You got {g} gold");
        }
        if self.floor.amulet == Some(i) {
            self.floor.amulet = None;
            self.won = true;
            self.terminated = true;
            self.touch(i);
            self.set_message("You got the Amulet of Yendor!");
        }
    }

    /// Searches the 8 neighbours: a hidden passage is found with P 1/passage_unlock_rate_inv,
    /// a secret door with P 1/door_unlock_rate_inv.
    pub(crate) fn search(&mut self) {
        let (x, y) = self.floor.xy(self.player.pos);
        for dir in Dir::ALL {
            let (dx, dy) = dir.delta();
            let (nx, ny) = (x + dx, y + dy);
            if !self.floor.in_area(nx, ny) {
                continue;
            }
            let i = self.floor.idx(nx, ny);
            let f = self.floor.flags[i];
            if f & flag::HIDDEN != 0 {
                if self.search_roll(self.cfg.dungeon.passage_unlock_rate_inv) {
                    self.floor.flags[i] &= !flag::HIDDEN;
                    self.floor.surface[i] = Surface::Passage;
                    self.reveal(i);
                }
            } else if f & flag::LOCKED != 0
                && self.search_roll(self.cfg.dungeon.door_unlock_rate_inv)
            {
                self.floor.flags[i] &= !flag::LOCKED;
                self.floor.surface[i] = Surface::Door;
                self.reveal(i);
                self.set_message("You found a secret door");
            }
        }
    }

    /// A search's `one_in(inv)`: from the play stream, or under `"seeding": "original"` from
    /// the original's dungeon stream (so searching shifts the floors below, as there).
    fn search_roll(&mut self, inv: u32) -> bool {
        match &mut self.original {
            Some(streams) => streams.dungeon.one_in(inv),
            None => self.rng.one_in(inv),
        }
    }
}
