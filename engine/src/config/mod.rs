//! The game configuration: the original JSON schema (docs/rules.md §1), parsed with serde and
//! validated into errors that name the offending key.
//!
//! Every object denies unknown keys. Every key is optional except `dungeon.style`, which is
//! required whenever `dungeon` is given (as in the original). `{}` is the default game:
//! 80x24, 3x3 rooms, all 26 monsters.

mod builtin;
mod enemies;
mod error;
mod items;
mod keymap;
mod player;
mod validate;

pub use builtin::{CONFUSED, MEAN, RANDOM};
pub(crate) use enemies::EnemyKind;
pub use enemies::{Chase, CustomEnemy, EnemiesConfig, EnemyPreset};
pub use error::ConfigError;
pub use items::{
    ArmorConfig, ArmorPreset, CustomArmor, CustomWeapon, Dice, GoldConfig, ItemConfig,
    WeaponConfig, WeaponPreset,
};
pub use keymap::{InputCode, KeyAction, KeyDirection, SysCode};
pub use player::{InitArmor, InitItem, InitWeapon, ItemKind, NoinitItem, PlayerConfig};

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Number of symbols without monsters: blank, `@`, `#`, `.`, wall, `%`, `+`, `^`, 8 item kinds, `,`.
pub const BASE_SYMBOLS: usize = 17;

/// The whole game configuration (top level of the JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GameConfig {
    /// Screen width in cells, 32..=160 (default 80).
    pub width: i32,
    /// Screen height in cells, 16..=48 (default 24). Rows 0 and height-1 are the message and
    /// status lines, always blank in observations.
    pub height: i32,
    /// A fixed seed (see [`crate::Game::default_seed`]). The original took a u128; we take u64.
    pub seed: Option<u64>,
    /// `[lo, hi)`: used by [`GameConfig::seed_for_episode`] when `seed` is null.
    pub seed_range: Option<[u64; 2]>,
    /// How a seed becomes random streams (default [`Seeding::Mixed`]).
    pub seeding: Seeding,
    /// `false` shows the whole floor when it is created (hidden passages and secret doors
    /// still hidden). Default `true`.
    pub hide_dungeon: bool,
    /// Dungeon generation parameters.
    pub dungeon: DungeonConfig,
    /// Item parameters (gold piles; armour and weapon tables).
    pub item: ItemConfig,
    /// Player parameters.
    pub player: PlayerConfig,
    /// Monster list and appearance rates.
    pub enemies: EnemiesConfig,
    /// Key bindings for terminal play. `None` = the default keymap. A given keymap replaces
    /// the default one completely. The RL action space never depends on it. Not written when
    /// `None`: the original rejects `"keymap": null`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub keymap: Option<BTreeMap<String, InputCode>>,
}

impl Default for GameConfig {
    fn default() -> Self {
        GameConfig {
            width: 80,
            height: 24,
            seed: None,
            seed_range: None,
            seeding: Seeding::default(),
            hide_dungeon: true,
            dungeon: DungeonConfig::default(),
            item: ItemConfig::default(),
            player: PlayerConfig::default(),
            enemies: EnemiesConfig::default(),
            keymap: None,
        }
    }
}

/// How a seed becomes the game's random streams.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Seeding {
    /// Ours: independent ChaCha8 streams per (seed, subsystem, floor), mixed by splitmix64.
    /// Floor k depends only on (config, seed, k), whatever happened on the floors before.
    #[default]
    Mixed,
    /// The original's (v0.0.2): raw-seeded XorShift128 streams for the dungeon and the items,
    /// continued from floor to floor, so the paper's seeds give the paper's dungeons exactly.
    /// Floor k then depends on play: each search next to a hidden cell draws from the dungeon
    /// stream (engine/README.md, "Original seeding").
    Original,
}

/// Dungeon generation parameters (style `"rogue"`, docs/rules.md §1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DungeonConfig {
    /// Generator style: only `"rogue"` is supported. Required when `dungeon` is given.
    pub style: String,
    /// Room slots across (default 3).
    #[serde(default = "d_room_num")]
    pub room_num_x: i32,
    /// Room slots down (default 3).
    #[serde(default = "d_room_num")]
    pub room_num_y: i32,
    /// Minimum outer room size, walls included (default 4x4; at least 3x3).
    #[serde(default)]
    pub min_room_size: Coord,
    /// Unused, as in the original (no traps).
    #[serde(default = "d_true")]
    pub enable_trap: bool,
    /// Upper bound (inclusive) on gone rooms (default 3).
    #[serde(default = "d_max_empty_rooms")]
    pub max_empty_rooms: u32,
    /// Floor on which the amulet lies (and on every deeper floor); monsters deeper than this
    /// get a level bonus (default 25).
    #[serde(default = "d_amulet_level")]
    pub amulet_level: u32,
    /// A dark room is a maze with P 1/maze_rate_inv (default 15, >= 1).
    #[serde(default = "d_maze_rate_inv")]
    pub maze_rate_inv: u32,
    /// A room is dark with P min(level, dark_level)/dark_level (default 10, >= 1).
    #[serde(default = "d_dark_level")]
    pub dark_level: u32,
    /// Hidden passage cell rate (default 40, >= 1).
    #[serde(default = "d_hidden_passage_rate_inv")]
    pub hidden_passage_rate_inv: u32,
    /// Secret ("locked") door rate (default 5, >= 1).
    #[serde(default = "d_five")]
    pub locked_door_rate_inv: u32,
    /// Extra-edge attempts are drawn from `[0, max_extra_edges)` (default 5). 0 means no extra
    /// edges (the original panicked).
    #[serde(default = "d_five")]
    pub max_extra_edges: u32,
    /// Search finds a secret door with P 1/door_unlock_rate_inv (default 5, >= 1).
    #[serde(default = "d_five")]
    pub door_unlock_rate_inv: u32,
    /// Search finds a hidden passage with P 1/passage_unlock_rate_inv (default 3, >= 1).
    #[serde(default = "d_three")]
    pub passage_unlock_rate_inv: u32,
}

fn d_room_num() -> i32 {
    3
}
fn d_true() -> bool {
    true
}
fn d_max_empty_rooms() -> u32 {
    3
}
fn d_amulet_level() -> u32 {
    25
}
fn d_maze_rate_inv() -> u32 {
    15
}
fn d_dark_level() -> u32 {
    10
}
fn d_hidden_passage_rate_inv() -> u32 {
    40
}
fn d_five() -> u32 {
    5
}
fn d_three() -> u32 {
    3
}

impl Default for DungeonConfig {
    fn default() -> Self {
        DungeonConfig {
            style: "rogue".to_string(),
            room_num_x: 3,
            room_num_y: 3,
            min_room_size: Coord::default(),
            enable_trap: true,
            max_empty_rooms: 3,
            amulet_level: 25,
            maze_rate_inv: 15,
            dark_level: 10,
            hidden_passage_rate_inv: 40,
            locked_door_rate_inv: 5,
            max_extra_edges: 5,
            door_unlock_rate_inv: 5,
            passage_unlock_rate_inv: 3,
        }
    }
}

/// A 2-D size `{"x": .., "y": ..}`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Coord {
    /// Columns.
    pub x: i32,
    /// Rows.
    pub y: i32,
}

impl Default for Coord {
    fn default() -> Self {
        Coord { x: 4, y: 4 }
    }
}

impl GameConfig {
    /// Parses and validates a JSON config. Unknown keys and bad values are errors naming the key.
    pub fn from_json(json: &str) -> Result<GameConfig, ConfigError> {
        let de = &mut serde_json::Deserializer::from_str(json);
        let cfg: GameConfig =
            serde_path_to_error::deserialize(de).map_err(ConfigError::from_serde)?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Serialises the whole config (every key, defaults included) as JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_else(|_| "{}".to_string())
    }

    /// The paper's configuration (docs/rules.md §1): 32x16, 2x2 rooms, no monsters,
    /// `seed_range` [0, 40).
    pub fn paper() -> GameConfig {
        GameConfig {
            width: 32,
            height: 16,
            seed_range: Some([0, 40]),
            dungeon: DungeonConfig {
                room_num_x: 2,
                room_num_y: 2,
                ..DungeonConfig::default()
            },
            enemies: EnemiesConfig {
                enemies: Vec::new(),
                ..EnemiesConfig::default()
            },
            ..GameConfig::default()
        }
    }

    /// Number of observation symbols: 17, plus (index of the highest monster letter + 1) when
    /// monsters are on: 43 with all 26, 19 with the bat only.
    pub fn symbol_count(&self) -> usize {
        let max_letter = self
            .enemies
            .enemies
            .iter()
            .filter_map(|p| p.resolve())
            .filter(|k| k.tile.is_ascii_uppercase())
            .map(|k| (k.tile - b'A') as usize + 1)
            .max()
            .unwrap_or(0);
        BASE_SYMBOLS + max_letter
    }

    /// The seed for the `episode`-th episode when the caller does not pick one: `seed` if set,
    /// else `lo + splitmix64(episode) % (hi - lo)` for `seed_range` [lo, hi), else `episode`.
    /// Deterministic (the original drew from the OS).
    pub fn seed_for_episode(&self, episode: u64) -> u64 {
        if let Some(s) = self.seed {
            s
        } else if let Some([lo, hi]) = self.seed_range {
            lo + crate::rng::splitmix64(episode) % hi.saturating_sub(lo).max(1)
        } else {
            episode
        }
    }

    /// Room slot size `(slot_w, slot_h)` before the per-row adjustments.
    pub(crate) fn slot_size(&self) -> (i32, i32) {
        (
            self.width / self.dungeon.room_num_x.max(1),
            self.height / self.dungeon.room_num_y.max(1),
        )
    }
}
