//! The `player` section: starting stats and items.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// Player parameters (docs/rules.md §1).
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
                    kind: ItemKind::Plain("Gold".into()),
                    how_many: 0,
                    attr: 4,
                }),
                InitItem::Noinit(NoinitItem {
                    kind: ItemKind::WithSub(BTreeMap::from([("Food".into(), "Ration".into())])),
                    how_many: 1,
                    attr: 4,
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
    /// Item kind: `"Gold"` (sets the starting gold), or a kind with its sub-kind as the original
    /// writes it, `{"Food": "Ration"}`.
    pub kind: ItemKind,
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

/// The kind of a plain starting item, in the original's two spellings.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ItemKind {
    /// A kind alone: `"Gold"`.
    Plain(String),
    /// A kind and its sub-kind, externally tagged as in the original: `{"Food": "Ration"}`
    /// (one entry).
    WithSub(BTreeMap<String, String>),
}

impl ItemKind {
    /// The kind's name (`"Gold"`, `"Food"`, ...); empty for a malformed sub-kind map.
    pub fn name(&self) -> &str {
        match self {
            ItemKind::Plain(k) => k,
            ItemKind::WithSub(m) => m.keys().next().map_or("", String::as_str),
        }
    }
}
