//! The per-turn tick (docs/rules.md §6): hunger (starvation kills), healing, then monsters.

use crate::game::Game;

impl Game {
    /// One turn passes after the player's action.
    pub(crate) fn after_turn(&mut self) {
        self.player.food = self.player.food.saturating_sub(1);
        if self.player.food == 0 {
            self.player.hp = 0;
            self.die("Starved to death");
            return;
        }
        self.heal();
        if !self.enemies.is_empty() {
            self.enemies_act();
        }
    }

    /// 0 normal, 1 hungry (food <= 2T/10), 2 weak (food <= T/10), T = hunger_time.
    pub(crate) fn hunger_level(&self) -> u32 {
        let t = self.cfg.player.hunger_time;
        if self.player.food <= t / 10 {
            2
        } else if self.player.food <= 2 * (t / 10) {
            1
        } else {
            0
        }
    }

    fn heal(&mut self) {
        let p = &mut self.player;
        p.quiet += 1;
        let amount = if p.level < 8 {
            i32::from(p.quiet + 2 * p.level >= 21)
        } else if p.quiet >= 3 {
            self.rng.range(1, p.level as i32 - 6)
        } else {
            0
        };
        if amount > 0 {
            p.hp = (p.hp + amount).min(p.max_hp);
            p.quiet = 0;
        }
    }
}
