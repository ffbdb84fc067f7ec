//! The `enemies` section: which monsters appear, and their resolved kinds.

use serde::{Deserialize, Serialize};

use super::Dice;
use super::builtin::ENEMIES;

/// Monster settings (docs/rules.md §1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EnemiesConfig {
    /// Builtin indices (0..26, one per letter) or custom monsters. `[]` disables monsters.
    pub enemies: Vec<EnemyPreset>,
    /// Percent chance of a monster in a room with gold (default 80, <= 100).
    pub appear_rate_gold: u32,
    /// Percent chance of a monster in a room without gold (default 25, <= 100).
    pub appear_rate_nogold: u32,
    /// How a chasing monster steps (default [`Chase::Closer`]; ours, not the original's key).
    pub chase: Chase,
    /// May a monster start on gold or the stairs, as in the original? Default `false` (ours,
    /// not the original's key): a monster there hides the object under it.
    pub spawn_on_objects: bool,
}

/// How a chasing monster picks its step, along BFS distances from the player.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Chase {
    /// Ours: only to a strictly closer cell, and the step obeys the diagonal rule, so a
    /// monster blocked by another waits.
    #[default]
    Closer,
    /// The original's: to the free neighbour nearest the player even when it is no closer
    /// (a side-step around a blocker), the step itself unchecked against corners. Harder.
    Original,
}

impl Default for EnemiesConfig {
    fn default() -> Self {
        EnemiesConfig {
            enemies: (0..26).map(EnemyPreset::Builtin).collect(),
            appear_rate_gold: 80,
            appear_rate_nogold: 25,
            chase: Chase::default(),
            spawn_on_objects: false,
        }
    }
}

/// A monster preset: a builtin index or a custom monster.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum EnemyPreset {
    /// Index into the builtin table (0 = A .. 25 = Z).
    Builtin(usize),
    /// A custom monster.
    Custom(CustomEnemy),
}

/// A custom monster (the original's field names).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CustomEnemy {
    /// Attack dice.
    pub attack: Vec<Dice>,
    /// Attribute bits (MEAN=1, RANDOM=512, CONFUSED=1024, ...).
    #[serde(default)]
    pub attr: u16,
    /// Rogue-style armour class (higher is easier to hit).
    pub defense: i32,
    /// Experience given when killed.
    pub exp: u32,
    /// Unused.
    #[serde(default)]
    pub gold: u32,
    /// Level (>= 1).
    pub level: u32,
    /// Name.
    pub name: String,
    /// The ASCII byte of its letter, `A`..=`Z` (65..=90).
    pub tile: u8,
    /// Rarity: lower appears earlier in the dungeon.
    #[serde(default)]
    pub rarelity: u8,
}

/// A resolved monster kind (builtin or custom), used by the engine.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct EnemyKind {
    pub tile: u8,
    pub name: String,
    pub level: u32,
    pub defense: i32,
    pub exp: u32,
    pub attack: Vec<(u32, u32)>,
    pub attr: u16,
    pub rarity: u8,
}

impl EnemyPreset {
    /// Resolves the preset; `None` for an invalid builtin index.
    pub(crate) fn resolve(&self) -> Option<EnemyKind> {
        match self {
            EnemyPreset::Builtin(i) => ENEMIES.get(*i).map(|b| EnemyKind {
                tile: b.tile,
                name: b.name.to_string(),
                level: b.level,
                defense: b.defense,
                exp: b.exp,
                attack: b.attack.to_vec(),
                attr: b.attr,
                rarity: b.rarity,
            }),
            EnemyPreset::Custom(c) => Some(EnemyKind {
                tile: c.tile,
                name: c.name.clone(),
                level: c.level,
                defense: c.defense,
                exp: c.exp,
                attack: c.attack.iter().map(|d| (d.times, d.max)).collect(),
                attr: c.attr,
                rarity: c.rarelity,
            }),
        }
    }
}
