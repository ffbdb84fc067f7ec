//! Monsters: placement on a new floor (docs/rules.md §7.2) and their turn (§7.4): random
//! steps for RANDOM/CONFUSED kinds, otherwise a chase along a BFS distance map from the player.
//! Fixes: real HP, the diagonal rule applies to chase steps, no border panic, no monster is
//! lost on collision (a monster never moves onto another).

use crate::actors::Enemy;
use crate::config::{CONFUSED, Chase, RANDOM};
use crate::dungeon::{RoomKind, Surface};
use crate::game::Game;
use crate::geometry::Dir;
use crate::rng::{GameRng, Stream};

/// What a chasing monster does this turn.
enum ChaseStep {
    /// Attack the player.
    Attack,
    /// Step onto this cell.
    Move(usize),
    /// Stay.
    Wait,
}

impl Game {
    /// Places monsters on the new floor: one roll per real room (monster stream of the floor),
    /// never on `avoid` (the player's start when it is already chosen).
    pub(crate) fn place_enemies(&mut self, avoid: Option<usize>) {
        if self.kinds.is_empty() {
            return;
        }
        let mut rng = GameRng::new(self.seed, Stream::Enemies, u64::from(self.level));
        let level = self.level as i32;
        let count = self.kinds.len() as i32;
        for r in 0..self.floor.rooms.len() {
            let room = self.floor.rooms[r];
            if room.kind == RoomKind::Gone {
                continue;
            }
            // Ours: an empty cell; with `spawn_on_objects`, the original's rule (gold and the
            // stairs allowed).
            let cell = if self.cfg.enemies.spawn_on_objects {
                self.generator
                    .random_cell_where(&self.floor, &mut rng, r, |f, i| {
                        matches!(
                            f.surface[i],
                            Surface::Floor | Surface::Passage | Surface::Stair
                        )
                    })
            } else {
                self.generator.random_empty_cell(&self.floor, &mut rng, r)
            };
            let Some(cell) = cell else {
                continue;
            };
            if avoid == Some(cell) {
                continue;
            }
            let rate = if room.has_gold {
                self.cfg.enemies.appear_rate_gold
            } else {
                self.cfg.enemies.appear_rate_nogold
            };
            if !rng.percent(rate) {
                continue;
            }
            let mut id = rng.range((level - 4).max(0), level + 6);
            if id > count {
                id = rng.range(count - count.min(5), count);
            }
            if id >= count {
                continue;
            }
            let kind = &self.kinds[id as usize];
            let lev_add = self.level.saturating_sub(self.cfg.dungeon.amulet_level);
            let elevel = kind.level + lev_add;
            let hp = rng.dice(8, elevel).max(1);
            let per = if elevel == 1 { hp / 8 } else { hp / 6 };
            let exp = kind
                .exp
                .saturating_add(lev_add.saturating_mul(10))
                .saturating_add((per as u32).saturating_mul(if elevel >= 10 { 20 } else { 4 }));
            self.enemies.push(Enemy {
                kind: id as u16,
                pos: cell,
                hp,
                level: elevel,
                defense: kind.defense - lev_add as i32,
                exp,
                awake: false,
                alive: true,
            });
            self.enemy_at[cell] = self.enemies.len() as u16;
        }
    }

    /// Every awake monster acts once.
    pub(crate) fn enemies_act(&mut self) {
        let mut have_map = false;
        for k in 0..self.enemies.len() {
            if self.terminated {
                return;
            }
            let e = self.enemies[k];
            if !e.alive || !e.awake {
                continue;
            }
            let attr = self.kinds[e.kind as usize].attr;
            let random = (self.rng.below(2) == 0 && attr & RANDOM != 0)
                || (self.rng.below(5) != 0 && attr & CONFUSED != 0);
            if random {
                let dir = Dir::ALL[self.rng.below(8) as usize];
                if let Some(t) = self.can_move(e.pos, dir) {
                    if t == self.player.pos {
                        self.enemy_attack(k);
                    } else if self.enemy_at[t] == 0 {
                        self.move_enemy(k, t);
                    }
                }
                continue;
            }
            if !have_map {
                self.chase_map();
                have_map = true;
            }
            let step = match self.cfg.enemies.chase {
                Chase::Closer => self.chase_closer(e.pos),
                Chase::Original => self.chase_original(e.pos),
            };
            match step {
                ChaseStep::Attack => self.enemy_attack(k),
                ChaseStep::Move(t) => self.move_enemy(k, t),
                ChaseStep::Wait => {}
            }
        }
    }

    /// [`Chase::Closer`]: the nearest strictly closer legal step (first in direction order on
    /// ties), or an attack when the player is a legal step away.
    fn chase_closer(&self, from: usize) -> ChaseStep {
        let here = self.dist[from];
        let mut best: Option<(u16, usize)> = None;
        for dir in Dir::ALL {
            let Some(t) = self.can_move(from, dir) else {
                continue;
            };
            if t == self.player.pos {
                return ChaseStep::Attack;
            }
            if self.enemy_at[t] != 0 {
                continue;
            }
            let d = self.dist[t];
            if d < here && best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, t));
            }
        }
        best.map_or(ChaseStep::Wait, |(_, t)| ChaseStep::Move(t))
    }

    /// [`Chase::Original`]: the free neighbour with the least distance (first in direction
    /// order on ties), even when no closer; the player next door is attacked only across a
    /// legal step, but a move is not checked against corners.
    fn chase_original(&self, from: usize) -> ChaseStep {
        let (x, y) = self.floor.xy(from);
        let mut best: Option<(u16, usize)> = None;
        for dir in Dir::ALL {
            let (dx, dy) = dir.delta();
            if !self.floor.in_area(x + dx, y + dy) {
                continue;
            }
            let t = self.floor.idx(x + dx, y + dy);
            if self.enemy_at[t] != 0 {
                continue;
            }
            let d = self.dist[t];
            if d == 0 {
                if self.can_move(from, dir).is_some() {
                    return ChaseStep::Attack;
                }
            } else if d != u16::MAX && best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, t));
            }
        }
        best.map_or(ChaseStep::Wait, |(_, t)| ChaseStep::Move(t))
    }

    fn move_enemy(&mut self, k: usize, t: usize) {
        let from = self.enemies[k].pos;
        self.enemy_at[from] = 0;
        self.enemy_at[t] = k as u16 + 1;
        self.enemies[k].pos = t;
        self.touch(from);
        self.touch(t);
    }

    /// BFS distances (8-neighbourhood, monster moves) from the player into `self.dist`.
    fn chase_map(&mut self) {
        self.dist.fill(u16::MAX);
        self.queue.clear();
        let start = self.player.pos;
        self.dist[start] = 0;
        self.queue.push(start as u32);
        let mut head = 0;
        while head < self.queue.len() {
            let c = self.queue[head] as usize;
            head += 1;
            let d = self.dist[c];
            for dir in Dir::ALL {
                if let Some(t) = self.can_move(c, dir)
                    && self.dist[t] == u16::MAX
                {
                    self.dist[t] = d + 1;
                    self.queue.push(t as u32);
                }
            }
        }
    }
}
