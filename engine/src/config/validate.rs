//! Validation of a [`GameConfig`], one function per section; each error names its key.

use super::keymap;
use super::{ArmorPreset, ConfigError, EnemyPreset, GameConfig, InitItem, ItemKind, WeaponPreset};

/// Most extra-edge attempts a floor may make (`dungeon.max_extra_edges`).
pub(crate) const MAX_EXTRA_EDGES: u32 = 10_000;

impl GameConfig {
    /// Checks every value. Returns the first problem found, naming its key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        screen(self)?;
        dungeon(self)?;
        items(self)?;
        player(self)?;
        enemies(self)?;
        keymap(self)
    }
}

/// The screen size and the seed range.
fn screen(c: &GameConfig) -> Result<(), ConfigError> {
    if !(32..=160).contains(&c.width) {
        return Err(ConfigError::invalid(
            "width",
            c.width,
            "is out of range: must be 32..=160",
        ));
    }
    if !(16..=48).contains(&c.height) {
        return Err(ConfigError::invalid(
            "height",
            c.height,
            "is out of range: must be 16..=48",
        ));
    }
    if let Some([lo, hi]) = c.seed_range
        && lo >= hi
    {
        return Err(ConfigError::invalid(
            "seed_range",
            format!("[{lo}, {hi}]"),
            "must be [lo, hi) with lo < hi",
        ));
    }
    Ok(())
}

/// The `dungeon` section, and room slots that fit the screen.
fn dungeon(c: &GameConfig) -> Result<(), ConfigError> {
    let d = &c.dungeon;
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
    if d.room_num_x
        .checked_mul(d.room_num_y)
        .is_none_or(|n| n > 255)
    {
        return Err(ConfigError::invalid(
            "dungeon.room_num_x",
            d.room_num_x,
            "room_num_x * room_num_y must be <= 255",
        ));
    }
    // Each extra-edge attempt is a loop turn during generation: bound them, so a huge value is
    // an error rather than minutes of generation per floor.
    if d.max_extra_edges > MAX_EXTRA_EDGES {
        return Err(ConfigError::invalid(
            "dungeon.max_extra_edges",
            d.max_extra_edges,
            format!("must be <= {MAX_EXTRA_EDGES}"),
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
    let (sw, sh) = c.slot_size();
    // Slot height on row 0 is reduced by one, and the last row may be too.
    let min_sh = sh - 1 - i32::from(d.room_num_y == 1);
    if d.min_room_size.x >= sw {
        return Err(ConfigError::invalid(
            "dungeon.min_room_size.x",
            d.min_room_size.x,
            format!(
                "is too large: the room slots are too small for it: must be < the slot width {sw} (= width {} / room_num_x {})",
                c.width, d.room_num_x
            ),
        ));
    }
    if d.min_room_size.y >= min_sh {
        return Err(ConfigError::invalid(
            "dungeon.min_room_size.y",
            d.min_room_size.y,
            format!(
                "is too large: the room slots are too small for it: must be < the smallest slot height {min_sh} (height {} / room_num_y {}, minus border rows)",
                c.height, d.room_num_y
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
        ("item.gold.rate_inv", c.item.gold.rate_inv),
        ("player.hunger_time", c.player.hunger_time),
    ] {
        if v < 1 {
            return Err(ConfigError::invalid(key, v, "must be >= 1"));
        }
    }
    Ok(())
}

/// The `item` section: gold, armour and weapon presets.
fn items(c: &GameConfig) -> Result<(), ConfigError> {
    if c.item
        .gold
        .base
        .saturating_add(c.item.gold.per_level.saturating_mul(1000))
        == 0
    {
        return Err(ConfigError::invalid(
            "item.gold.base",
            0,
            "base and per_level cannot both be 0",
        ));
    }
    if c.item.gold.base > 1_000_000
        || c.item.gold.per_level > 1_000_000
        || c.item.gold.minimum > 1_000_000
    {
        return Err(ConfigError::invalid(
            "item.gold",
            c.item.gold.base,
            "amounts must be <= 1000000",
        ));
    }
    for (i, a) in c.item.armor.armors.iter().enumerate() {
        match a {
            ArmorPreset::Builtin(idx) if *idx >= 8 => {
                return Err(ConfigError::invalid(
                    &format!("item.armor.armors[{i}]"),
                    idx,
                    "builtin armour index must be 0..8",
                ));
            }
            ArmorPreset::Custom(c) if c.def.unsigned_abs() > 100 => {
                return Err(ConfigError::invalid(
                    &format!("item.armor.armors[{i}].def"),
                    c.def,
                    "must be -100..=100",
                ));
            }
            _ => {}
        }
    }
    for (i, w) in c.item.weapon.weapons.iter().enumerate() {
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
    Ok(())
}

/// The `player` section.
fn player(c: &GameConfig) -> Result<(), ConfigError> {
    let p = &c.player;
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
    // The original's files end the list with a 0 (a sentinel it never reaches in play); the
    // level-up rule reads it the same way here, so only the thresholds before it must rise.
    let thresholds = p.exps.strip_suffix(&[0]).unwrap_or(&p.exps);
    if thresholds.windows(2).any(|w| w[0] > w[1]) {
        return Err(ConfigError::invalid(
            "player.exps",
            format!("{:?}", p.exps),
            "thresholds must be non-decreasing",
        ));
    }
    for (i, item) in p.init_items.iter().enumerate() {
        if let InitItem::Noinit(n) = item
            && let ItemKind::WithSub(m) = &n.kind
            && m.len() != 1
        {
            return Err(ConfigError::invalid(
                &format!("player.init_items[{i}].kind"),
                format!("{m:?}"),
                "a kind with a sub-kind has exactly one entry, e.g. {\"Food\": \"Ration\"}",
            ));
        }
        match item {
            InitItem::Armor(a) if c.item.armor.defense_of(&a.name).is_none() => {
                return Err(ConfigError::invalid(
                    &format!("player.init_items[{i}].name"),
                    format!("{:?}", a.name),
                    "no armour of that name in item.armor.armors",
                ));
            }
            InitItem::Weapon(w) if c.item.weapon.dice_of(&w.name).is_none() => {
                return Err(ConfigError::invalid(
                    &format!("player.init_items[{i}].name"),
                    format!("{:?}", w.name),
                    "no weapon of that name in item.weapon.weapons",
                ));
            }
            InitItem::Armor(a) if a.def_plus.unsigned_abs() > 100 => {
                return Err(ConfigError::invalid(
                    &format!("player.init_items[{i}].def_plus"),
                    a.def_plus,
                    "must be -100..=100",
                ));
            }
            InitItem::Weapon(w)
                if w.hit_plus.unsigned_abs() > 100 || w.dam_plus.unsigned_abs() > 100 =>
            {
                return Err(ConfigError::invalid(
                    &format!("player.init_items[{i}]"),
                    w.hit_plus,
                    "hit_plus and dam_plus must be -100..=100",
                ));
            }
            _ => {}
        }
    }
    Ok(())
}

/// The `enemies` section.
fn enemies(c: &GameConfig) -> Result<(), ConfigError> {
    let e = &c.enemies;
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
                if c.defense.unsigned_abs() > 1000 {
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
    Ok(())
}

/// The `keymap`: every key must be a key name.
fn keymap(c: &GameConfig) -> Result<(), ConfigError> {
    if let Some(km) = &c.keymap {
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
