//! The game configuration: the original JSON schema (engine-spec §1), parsed with serde and
//! validated into errors that name the offending key.
//!
//! Every object denies unknown keys. Every key is optional except `dungeon.style`, which is
//! required whenever `dungeon` is given (as in the original). `{}` is the default game:
//! 80x24, 3x3 rooms, all 26 monsters.

mod builtin;
mod error;
mod keymap;

pub use builtin::{CONFUSED, MEAN, RANDOM};
pub(crate) use builtin::{ENEMIES, armor_by_name, weapon_by_name};
pub use error::ConfigError;
pub use keymap::{InputCode, KeyAction, KeyDirection, SysCode};

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
    /// the default one completely. The RL action space never depends on it.
    pub keymap: Option<BTreeMap<String, InputCode>>,
}

impl Default for GameConfig {
    fn default() -> Self {
        GameConfig {
            width: 80,
            height: 24,
            seed: None,
            seed_range: None,
            hide_dungeon: true,
            dungeon: DungeonConfig::default(),
            item: ItemConfig::default(),
            player: PlayerConfig::default(),
            enemies: EnemiesConfig::default(),
            keymap: None,
        }
    }
}

/// Dungeon generation parameters (style `"rogue"`, engine-spec §1.2).
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

/// Item parameters (engine-spec §1.3). Each sub-object defaults when omitted (the original
/// required all three; we are lenient).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ItemConfig {
    /// Armour table (only used for the starting inventory).
    pub armor: ArmorConfig,
    /// Gold piles.
    pub gold: GoldConfig,
    /// Weapon table (only used for the starting inventory).
    pub weapon: WeaponConfig,
}

/// Armour table settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArmorConfig {
    /// Builtin indices (0..8) or custom armours.
    pub armors: Vec<ArmorPreset>,
    /// Percent cursed (unused: no random armour is generated).
    pub cursed_rate: u32,
    /// Percent powered-up (unused).
    pub powerup_rate: u32,
}

impl Default for ArmorConfig {
    fn default() -> Self {
        ArmorConfig {
            armors: (0..8).map(ArmorPreset::Builtin).collect(),
            cursed_rate: 20,
            powerup_rate: 8,
        }
    }
}

/// An armour preset: a builtin index or a custom armour.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ArmorPreset {
    /// Index into the builtin table (0..8).
    Builtin(usize),
    /// A custom armour.
    Custom(CustomArmor),
}

/// A custom armour.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CustomArmor {
    /// Name.
    pub name: String,
    /// Base defence.
    pub def: i32,
}

/// Weapon table settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WeaponConfig {
    /// Builtin indices (0..9) or custom weapons.
    pub weapons: Vec<WeaponPreset>,
    /// Percent cursed (unused).
    pub cursed_rate: u32,
    /// Percent powered-up (unused).
    pub powerup_rate: u32,
}

impl Default for WeaponConfig {
    fn default() -> Self {
        WeaponConfig {
            weapons: (0..9).map(WeaponPreset::Builtin).collect(),
            cursed_rate: 10,
            powerup_rate: 5,
        }
    }
}

/// A weapon preset: a builtin index or a custom weapon.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum WeaponPreset {
    /// Index into the builtin table (0..9).
    Builtin(usize),
    /// A custom weapon.
    Custom(CustomWeapon),
}

/// A custom weapon.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CustomWeapon {
    /// Name.
    pub name: String,
    /// Wield dice.
    pub dice: Dice,
}

/// Gold pile settings (engine-spec §7).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GoldConfig {
    /// A room gets gold with P 1/rate_inv (default 2, >= 1).
    pub rate_inv: u32,
    /// Amount is `minimum + rand[0, base + per_level*level)` (base default 50).
    pub base: u32,
    /// Per-level amount increase (default 10).
    pub per_level: u32,
    /// Minimum amount (default 2).
    pub minimum: u32,
}

impl Default for GoldConfig {
    fn default() -> Self {
        GoldConfig {
            rate_inv: 2,
            base: 50,
            per_level: 10,
            minimum: 2,
        }
    }
}

/// Dice `{"times": n, "max": m}`: n rolls of 1..=m.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Dice {
    /// Number of rolls.
    pub times: u32,
    /// Faces of each die.
    pub max: u32,
}

/// Player parameters (engine-spec §1.4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlayerConfig {
    /// Exp thresholds for levels 2, 3, ... (non-decreasing).
    pub exps: Vec<u32>,
    /// Starting food; the player starves when it runs out (default 1300, >= 1).
    pub hunger_time: u32,
    /// Starting HP (default 12, >= 1).
    pub init_hp: i32,
    /// Starting strength (default 16, 1..=32). The original ignored it; we use it.
    pub init_str: i32,
    /// Pack slots (unused beyond validation).
    pub max_items: u32,
    /// Starting inventory. The first armour is worn, the first weapon wielded.
    pub init_items: Vec<InitItem>,
    /// Unused, as in the original.
    pub heal_threshold: u32,
}

impl Default for PlayerConfig {
    fn default() -> Self {
        PlayerConfig {
            exps: vec![
                10,
                20,
                40,
                80,
                160,
                320,
                640,
                1300,
                2600,
                5200,
                13000,
                26000,
                50000,
                100000,
                200000,
                400000,
                800000,
                2000000,
                4000000,
                8000000,
                u32::MAX,
            ],
            hunger_time: 1300,
            init_hp: 12,
            init_str: 16,
            max_items: 27,
            init_items: vec![
                InitItem::Noinit(NoinitItem {
                    kind: "Gold".into(),
                    how_many: 0,
                    attr: 4,
                }),
                InitItem::Noinit(NoinitItem {
                    kind: "Food".into(),
                    how_many: 1,
                    attr: 0,
                }),
                InitItem::Armor(InitArmor {
                    name: "ring mail".into(),
                    def_plus: 1,
                }),
                InitItem::Weapon(InitWeapon {
                    name: "mace".into(),
                    num_plus: 0,
                    hit_plus: 1,
                    dam_plus: 1,
                }),
                InitItem::Weapon(InitWeapon {
                    name: "bow".into(),
                    num_plus: 0,
                    hit_plus: 1,
                    dam_plus: 0,
                }),
                InitItem::Weapon(InitWeapon {
                    name: "arrow".into(),
                    num_plus: 25,
                    hit_plus: 0,
                    dam_plus: 0,
                }),
            ],
            heal_threshold: 20,
        }
    }
}

/// A starting item (externally tagged, as in the original).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum InitItem {
    /// A plain item: `{"Noinit": {"kind": "Gold", "how_many": 0, "attr": 4}}`.
    Noinit(NoinitItem),
    /// An armour by builtin name.
    Armor(InitArmor),
    /// A weapon by builtin name.
    Weapon(InitWeapon),
}

/// A plain starting item.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoinitItem {
    /// Item kind (`Gold`, `Food`, `Potion`, ...). Gold sets the starting gold.
    pub kind: String,
    /// Count.
    pub how_many: u32,
    /// Attribute bits (unused).
    #[serde(default)]
    pub attr: u32,
}

/// A starting armour.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitArmor {
    /// Builtin armour name, e.g. `ring mail`.
    pub name: String,
    /// Defence bonus.
    #[serde(default)]
    pub def_plus: i32,
}

/// A starting weapon.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitWeapon {
    /// Builtin weapon name, e.g. `mace`.
    pub name: String,
    /// Extra count.
    #[serde(default)]
    pub num_plus: u32,
    /// To-hit bonus.
    #[serde(default)]
    pub hit_plus: i32,
    /// Damage bonus.
    #[serde(default)]
    pub dam_plus: i32,
}

/// Monster settings (engine-spec §1.5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EnemiesConfig {
    /// Builtin indices (0..26, one per letter) or custom monsters. `[]` disables monsters.
    pub enemies: Vec<EnemyPreset>,
    /// Percent chance of a monster in a room with gold (default 80, <= 100).
    pub appear_rate_gold: u32,
    /// Percent chance of a monster in a room without gold (default 25, <= 100).
    pub appear_rate_nogold: u32,
}

impl Default for EnemiesConfig {
    fn default() -> Self {
        EnemiesConfig {
            enemies: (0..26).map(EnemyPreset::Builtin).collect(),
            appear_rate_gold: 80,
            appear_rate_nogold: 25,
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

    /// The paper's configuration (engine-spec §1.7): 32x16, 2x2 rooms, no monsters,
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

    /// Checks every value. Returns the first problem found, naming its key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(32..=160).contains(&self.width) {
            return Err(ConfigError::invalid(
                "width",
                self.width,
                "is out of range: must be 32..=160",
            ));
        }
        if !(16..=48).contains(&self.height) {
            return Err(ConfigError::invalid(
                "height",
                self.height,
                "is out of range: must be 16..=48",
            ));
        }
        if let Some([lo, hi]) = self.seed_range
            && lo >= hi
        {
            return Err(ConfigError::invalid(
                "seed_range",
                format!("[{lo}, {hi}]"),
                "must be [lo, hi) with lo < hi",
            ));
        }
        let d = &self.dungeon;
        if d.style != "rogue" {
            return Err(ConfigError::Unsupported {
                key: "dungeon.style".into(),
                value: format!("{:?}", d.style),
                reason: "only \"rogue\" is implemented".into(),
            });
        }
        if d.room_num_x < 1 || d.room_num_y < 1 {
            let (k, v) = if d.room_num_x < 1 {
                ("dungeon.room_num_x", d.room_num_x)
            } else {
                ("dungeon.room_num_y", d.room_num_y)
            };
            return Err(ConfigError::invalid(k, v, "must be >= 1"));
        }
        if d.room_num_x * d.room_num_y > 255 {
            return Err(ConfigError::invalid(
                "dungeon.room_num_x",
                d.room_num_x,
                "room_num_x * room_num_y must be <= 255",
            ));
        }
        if d.min_room_size.x < 3 || d.min_room_size.y < 3 {
            return Err(ConfigError::invalid(
                "dungeon.min_room_size",
                format!(
                    "{{\"x\": {}, \"y\": {}}}",
                    d.min_room_size.x, d.min_room_size.y
                ),
                "both sizes must be >= 3 (walls included)",
            ));
        }
        let (sw, sh) = self.slot_size();
        // Slot height on row 0 is reduced by one, and the last row may be too.
        let min_sh = sh - 1 - i32::from(d.room_num_y == 1);
        if d.min_room_size.x >= sw {
            return Err(ConfigError::invalid(
                "dungeon.min_room_size.x",
                d.min_room_size.x,
                format!(
                    "is too large: the room slots are too small for it: must be < the slot width {sw} (= width {} / room_num_x {})",
                    self.width, d.room_num_x
                ),
            ));
        }
        if d.min_room_size.y >= min_sh {
            return Err(ConfigError::invalid(
                "dungeon.min_room_size.y",
                d.min_room_size.y,
                format!(
                    "is too large: the room slots are too small for it: must be < the smallest slot height {min_sh} (height {} / room_num_y {}, minus border rows)",
                    self.height, d.room_num_y
                ),
            ));
        }
        for (key, v) in [
            ("dungeon.maze_rate_inv", d.maze_rate_inv),
            ("dungeon.dark_level", d.dark_level),
            ("dungeon.hidden_passage_rate_inv", d.hidden_passage_rate_inv),
            ("dungeon.locked_door_rate_inv", d.locked_door_rate_inv),
            ("dungeon.door_unlock_rate_inv", d.door_unlock_rate_inv),
            ("dungeon.passage_unlock_rate_inv", d.passage_unlock_rate_inv),
            ("dungeon.amulet_level", d.amulet_level),
            ("item.gold.rate_inv", self.item.gold.rate_inv),
            ("player.hunger_time", self.player.hunger_time),
        ] {
            if v < 1 {
                return Err(ConfigError::invalid(key, v, "must be >= 1"));
            }
        }
        if self
            .item
            .gold
            .base
            .saturating_add(self.item.gold.per_level.saturating_mul(1000))
            == 0
        {
            return Err(ConfigError::invalid(
                "item.gold.base",
                0,
                "base and per_level cannot both be 0",
            ));
        }
        if self.item.gold.base > 1_000_000
            || self.item.gold.per_level > 1_000_000
            || self.item.gold.minimum > 1_000_000
        {
            return Err(ConfigError::invalid(
                "item.gold",
                self.item.gold.base,
                "amounts must be <= 1000000",
            ));
        }
        for (i, a) in self.item.armor.armors.iter().enumerate() {
            if let ArmorPreset::Builtin(idx) = a
                && *idx >= 8
            {
                return Err(ConfigError::invalid(
                    &format!("item.armor.armors[{i}]"),
                    idx,
                    "builtin armour index must be 0..8",
                ));
            }
        }
        for (i, w) in self.item.weapon.weapons.iter().enumerate() {
            match w {
                WeaponPreset::Builtin(idx) if *idx >= 9 => {
                    return Err(ConfigError::invalid(
                        &format!("item.weapon.weapons[{i}]"),
                        idx,
                        "builtin weapon index must be 0..9",
                    ));
                }
                WeaponPreset::Custom(c) if c.dice.times > 100 || c.dice.max > 1000 => {
                    return Err(ConfigError::invalid(
                        &format!("item.weapon.weapons[{i}].dice"),
                        c.dice.times,
                        "dice too large (times <= 100, max <= 1000)",
                    ));
                }
                _ => {}
            }
        }
        let p = &self.player;
        if !(1..=100_000).contains(&p.init_hp) {
            return Err(ConfigError::invalid(
                "player.init_hp",
                p.init_hp,
                "must be 1..=100000",
            ));
        }
        if !(1..=32).contains(&p.init_str) {
            return Err(ConfigError::invalid(
                "player.init_str",
                p.init_str,
                "must be 1..=32",
            ));
        }
        if p.exps.windows(2).any(|w| w[0] > w[1]) {
            return Err(ConfigError::invalid(
                "player.exps",
                format!("{:?}", p.exps),
                "thresholds must be non-decreasing",
            ));
        }
        for (i, item) in p.init_items.iter().enumerate() {
            match item {
                InitItem::Armor(a) if armor_by_name(&a.name).is_none() => {
                    return Err(ConfigError::invalid(
                        &format!("player.init_items[{i}].name"),
                        format!("{:?}", a.name),
                        "unknown armour name",
                    ));
                }
                InitItem::Weapon(w) if weapon_by_name(&w.name).is_none() => {
                    return Err(ConfigError::invalid(
                        &format!("player.init_items[{i}].name"),
                        format!("{:?}", w.name),
                        "unknown weapon name",
                    ));
                }
                InitItem::Armor(a) if a.def_plus.abs() > 100 => {
                    return Err(ConfigError::invalid(
                        &format!("player.init_items[{i}].def_plus"),
                        a.def_plus,
                        "must be -100..=100",
                    ));
                }
                InitItem::Weapon(w) if w.hit_plus.abs() > 100 || w.dam_plus.abs() > 100 => {
                    return Err(ConfigError::invalid(
                        &format!("player.init_items[{i}]"),
                        w.hit_plus,
                        "hit_plus and dam_plus must be -100..=100",
                    ));
                }
                _ => {}
            }
        }
        let e = &self.enemies;
        for (key, v) in [
            ("enemies.appear_rate_gold", e.appear_rate_gold),
            ("enemies.appear_rate_nogold", e.appear_rate_nogold),
        ] {
            if v > 100 {
                return Err(ConfigError::invalid(key, v, "a percentage: must be <= 100"));
            }
        }
        for (i, preset) in e.enemies.iter().enumerate() {
            let key = format!("enemies.enemies[{i}]");
            match preset {
                EnemyPreset::Builtin(idx) if *idx >= 26 => {
                    return Err(ConfigError::invalid(
                        &key,
                        idx,
                        "builtin monster index must be 0..26",
                    ));
                }
                EnemyPreset::Custom(c) => {
                    if !c.tile.is_ascii_uppercase() {
                        return Err(ConfigError::invalid(
                            &format!("{key}.tile"),
                            c.tile,
                            "must be the byte of a letter A..=Z (65..=90)",
                        ));
                    }
                    if !(1..=1000).contains(&c.level) {
                        return Err(ConfigError::invalid(
                            &format!("{key}.level"),
                            c.level,
                            "must be 1..=1000",
                        ));
                    }
                    if c.attack.iter().any(|d| d.times > 100 || d.max > 1000) {
                        return Err(ConfigError::invalid(
                            &format!("{key}.attack"),
                            "..",
                            "dice too large (times <= 100, max <= 1000)",
                        ));
                    }
                    if c.defense.abs() > 1000 {
                        return Err(ConfigError::invalid(
                            &format!("{key}.defense"),
                            c.defense,
                            "must be -1000..=1000",
                        ));
                    }
                }
                _ => {}
            }
        }
        if let Some(km) = &self.keymap {
            for k in km.keys() {
                if keymap::parse_key(k).is_none() {
                    return Err(ConfigError::invalid(
                        "keymap",
                        format!("{k:?}"),
                        "not a key name",
                    ));
                }
            }
        }
        Ok(())
    }
}
