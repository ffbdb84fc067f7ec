//! The `item` section: armour, weapon and gold tables.

use serde::{Deserialize, Serialize};

use super::builtin::{ARMORS, WEAPON_COUNTS, WEAPONS, same_item_name};

/// Item parameters (docs/rules.md §1). Each sub-object defaults when omitted (the original
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

impl ArmorConfig {
    /// The base defence of the armour called `name` in this table (builtin entries by their
    /// builtin name, custom ones by theirs); `None` when the table has no such armour. The
    /// starting inventory is looked up here, as in the original.
    pub fn defense_of(&self, name: &str) -> Option<i32> {
        self.armors.iter().find_map(|preset| match preset {
            ArmorPreset::Builtin(i) => ARMORS
                .get(*i)
                .filter(|(n, _)| same_item_name(n, name))
                .map(|&(_, def)| def),
            ArmorPreset::Custom(c) => same_item_name(&c.name, name).then_some(c.def),
        })
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

impl WeaponConfig {
    /// The wield dice `(times, max)` of the weapon called `name` in this table (matched as
    /// [`ArmorConfig::defense_of`] does); `None` when the table has no such weapon.
    pub fn dice_of(&self, name: &str) -> Option<(u32, u32)> {
        self.weapons.iter().find_map(|preset| match preset {
            WeaponPreset::Builtin(i) => WEAPONS
                .get(*i)
                .filter(|(n, _)| same_item_name(n, name))
                .map(|&(_, dice)| dice),
            WeaponPreset::Custom(c) => {
                same_item_name(&c.name, name).then_some((c.dice.times, c.dice.max))
            }
        })
    }

    /// The stack size range `[lo, hi)` of the weapon called `name` in this table: the
    /// original's `init_num` for a builtin, `(1, 2)` for a custom weapon (ours have no
    /// count); `None` when the table has no such weapon.
    pub fn count_range_of(&self, name: &str) -> Option<(u32, u32)> {
        self.weapons.iter().find_map(|preset| match preset {
            WeaponPreset::Builtin(i) => WEAPONS
                .get(*i)
                .filter(|(n, _)| same_item_name(n, name))
                .and_then(|_| WEAPON_COUNTS.get(*i).copied()),
            WeaponPreset::Custom(c) => same_item_name(&c.name, name).then_some((1, 2)),
        })
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

/// Gold pile settings (docs/rules.md §5).
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
