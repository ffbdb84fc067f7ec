//! Melee (docs/rules.md §7.3) with the fixes: monsters have real HP (damage is subtracted),
//! monsters hit against the player's armour class `10 - defense`, and a monster's damage
//! does not add the player's strength bonus.

use crate::game::Game;

/// To-hit bonus of a strength (1..=32).
fn str_hit(s: i32) -> i32 {
    match s {
        i32::MIN..=0 => 0,
        1..=7 => s - 8,
        8..=17 => 0,
        18..=21 => 1,
        22..=31 => 2,
        _ => 3,
    }
}

/// Damage bonus of a strength.
fn str_dmg(s: i32) -> i32 {
    match s {
        i32::MIN..=0 => 0,
        1..=7 => s - 8,
        8..=16 => 0,
        17..=18 => 1,
        19 => 2,
        20..=21 => 3,
        22 => 4,
        23..=31 => 5,
        _ => 6,
    }
}

/// Percent chance to hit.
fn hit_chance(level: i32, armor: i32, bonus: i32) -> u32 {
    (5 * (level + armor + bonus + 1)).clamp(0, 100) as u32
}

impl Game {
    /// The player attacks monster `k`.
    pub(crate) fn player_attack(&mut self, k: usize) {
        self.player.quiet = 0;
        let e = self.enemies[k];
        // The original's attack wakes the monster before its roll, so its +4 against a sleeping
        // monster never applies; neither does it here (docs/rules.md §7.3).
        self.enemies[k].awake = true;
        let bonus = str_hit(self.player.str_cur) + self.player.hit_plus;
        let name = self.kinds[e.kind as usize].name.clone();
        if !self
            .rng
            .percent(hit_chance(self.player.level as i32, e.defense, bonus))
        {
            self.set_message(&format!("You miss the {name}"));
            return;
        }
        let (times, max) = self.player.weapon;
        let dmg = (self.rng.dice(times, max) + self.player.dam_plus + str_dmg(self.player.str_cur))
            .max(0);
        self.enemies[k].hp -= dmg;
        if self.enemies[k].hp > 0 {
            self.set_message(&format!("You hit the {name}"));
            return;
        }
        self.enemies[k].alive = false;
        self.enemy_at[e.pos] = 0;
        self.touch(e.pos);
        self.set_message(&format!("You defeated the {name}"));
        self.gain_exp(e.exp);
    }

    /// Adds experience and levels up (each level: +d10 max and current HP).
    fn gain_exp(&mut self, exp: u32) {
        self.player.exp = self.player.exp.saturating_add(exp);
        let exps = &self.cfg.player.exps;
        let mut diff = 0;
        while let Some(&need) = exps.get((self.player.level + diff) as usize - 1) {
            if need > self.player.exp {
                break;
            }
            diff += 1;
        }
        for _ in 0..diff {
            let add = self.rng.dice(1, 10);
            self.player.max_hp += add;
            self.player.hp += add;
        }
        self.player.level += diff;
    }

    /// Monster `k` attacks the player: each attack die hits separately.
    pub(crate) fn enemy_attack(&mut self, k: usize) {
        self.player.quiet = 0;
        let e = self.enemies[k];
        let kind = e.kind as usize;
        let armor_class = 10 - self.player.defense;
        let chance = hit_chance(e.level as i32, armor_class, 0);
        let mut dmg = 0;
        let mut hit = false;
        for a in 0..self.kinds[kind].attack.len() {
            let (times, max) = self.kinds[kind].attack[a];
            if times == 0 || max == 0 {
                continue;
            }
            if self.rng.percent(chance) {
                hit = true;
                dmg += self.rng.dice(times, max);
            }
        }
        let name = self.kinds[kind].name.clone();
        if !hit {
            self.set_message(&format!("The {name} misses you"));
            return;
        }
        self.player.hp -= dmg;
        self.set_message(&format!("The {name} hits you"));
        if self.player.hp <= 0 {
            self.player.hp = 0;
            self.die(&format!("Killed by {name}"));
        }
    }

    /// The player dies: the episode terminates.
    pub(crate) fn die(&mut self, cause: &str) {
        self.died = true;
        self.terminated = true;
        self.set_message(cause);
    }
}
