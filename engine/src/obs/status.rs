//! The player's status values, raw and normalised.

/// The player's status: the original's 9 status values plus gold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Status {
    /// Current floor (1-based).
    pub dungeon_level: u32,
    /// Gold carried.
    pub gold: u32,
    /// Current HP.
    pub hp_current: i32,
    /// Max HP.
    pub hp_max: i32,
    /// Current strength.
    pub str_current: i32,
    /// Max strength.
    pub str_max: i32,
    /// Armour defence (ring mail +1 = 4 at the start).
    pub defense: i32,
    /// Player level.
    pub player_level: u32,
    /// Experience points.
    pub exp: u32,
    /// 0 normal, 1 hungry, 2 weak.
    pub hunger: u32,
}

impl Status {
    /// The 9 values in flag order (dungeon level, hp, max hp, str, max str, defence, level,
    /// exp, hunger).
    pub fn values(&self) -> [i64; 9] {
        [
            i64::from(self.dungeon_level),
            i64::from(self.hp_current),
            i64::from(self.hp_max),
            i64::from(self.str_current),
            i64::from(self.str_max),
            i64::from(self.defense),
            i64::from(self.player_level),
            i64::from(self.exp),
            i64::from(self.hunger),
        ]
    }

    /// The 9 values normalised into [0, 1], in flag order: dungeon level / `amulet_level`,
    /// hp / max hp, max hp / 200, str / max str, max str / 32, defence / 20, player level / 21,
    /// exp / 100000, hunger / 2 (each clamped to [0, 1]).
    pub fn normalized(&self, amulet_level: u32) -> [f32; 9] {
        let r = |v: i64, cap: i64| -> f32 { (v.max(0) as f32 / cap.max(1) as f32).min(1.0) };
        let v = self.values();
        [
            r(v[0], i64::from(amulet_level)),
            r(v[1], v[2]),
            r(v[2], 200),
            r(v[3], v[4]),
            r(v[4], 32),
            r(v[5], 20),
            r(v[6], 21),
            r(v[7], 100_000),
            r(v[8], 2),
        ]
    }
}
