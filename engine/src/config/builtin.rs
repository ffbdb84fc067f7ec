//! Builtin tables of the original game: monsters, armours and weapons (docs/rules.md §5, §7.1).

/// Attribute flag: wakes up when the player enters its room.
pub const MEAN: u16 = 1;
/// Attribute flag: flies (no effect).
pub const FLYING: u16 = 2;
/// Attribute flag: regenerates (no effect).
pub const REGENERATE: u16 = 4;
/// Attribute flag: greedy (no effect).
pub const GREEDY: u16 = 8;
/// Attribute flag: invisible (no effect).
pub const INVISIBLE: u16 = 16;
/// Attribute flag: rusts armour (no effect).
pub const RUSTS_ARMOR: u16 = 32;
/// Attribute flag: steals gold (no effect).
pub const STEAL_GOLD: u16 = 64;
/// Attribute flag: reduces strength (no effect).
pub const REDUCE_STR: u16 = 128;
/// Attribute flag: freezes (no effect).
pub const FREEZES: u16 = 256;
/// Attribute flag: moves randomly half of the time.
pub const RANDOM: u16 = 512;
/// Attribute flag: moves randomly 4 times in 5 when not random.
pub const CONFUSED: u16 = 1024;

/// One builtin monster: (tile, name, level, defence (Rogue AC), exp, attack dice as (times, max), attrs, rarity).
pub(crate) struct BuiltinEnemy {
    pub tile: u8,
    pub name: &'static str,
    pub level: u32,
    pub defense: i32,
    pub exp: u32,
    pub attack: &'static [(u32, u32)],
    pub attr: u16,
    pub rarity: u8,
}

#[allow(clippy::too_many_arguments)]
const fn e(
    tile: u8,
    name: &'static str,
    level: u32,
    defense: i32,
    exp: u32,
    attack: &'static [(u32, u32)],
    attr: u16,
    rarity: u8,
) -> BuiltinEnemy {
    BuiltinEnemy {
        tile,
        name,
        level,
        defense,
        exp,
        attack,
        attr,
        rarity,
    }
}

/// The 26 builtin monsters, index = letter - 'A'.
pub(crate) const ENEMIES: [BuiltinEnemy; 26] = [
    e(
        b'A',
        "aquator",
        5,
        10,
        20,
        &[(0, 0)],
        MEAN | RUSTS_ARMOR,
        12,
    ),
    e(b'B', "bat", 1, 3, 1, &[(1, 2)], FLYING | RANDOM, 2),
    e(b'C', "centaur", 4, 4, 17, &[(1, 2), (1, 5), (1, 5)], 0, 10),
    e(
        b'D',
        "dragon",
        10,
        3,
        5000,
        &[(1, 8), (1, 8), (3, 10)],
        MEAN,
        25,
    ),
    e(b'E', "emu", 1, 7, 2, &[(1, 2)], MEAN, 1),
    e(b'F', "venus flytrap", 8, 3, 80, &[], MEAN, 15),
    e(
        b'G',
        "griffin",
        13,
        2,
        2000,
        &[(4, 3), (3, 5)],
        FLYING | MEAN | REGENERATE,
        23,
    ),
    e(b'H', "hobgoblin", 1, 5, 3, &[(1, 8)], MEAN, 4),
    e(b'I', "icemonster", 1, 9, 5, &[(0, 0)], FREEZES, 5),
    e(b'J', "jabberwock", 15, 6, 3000, &[(2, 12), (2, 4)], 0, 24),
    e(b'K', "kestrel", 1, 7, 1, &[(1, 4)], MEAN, 0),
    e(b'L', "leperachaun", 3, 8, 10, &[(1, 1)], STEAL_GOLD, 9),
    e(
        b'M',
        "medusa",
        8,
        2,
        200,
        &[(3, 4), (3, 4), (2, 5)],
        MEAN,
        21,
    ),
    e(b'N', "nymph", 3, 9, 37, &[(0, 0)], 0, 13),
    e(b'O', "orc", 1, 6, 5, &[(1, 8)], GREEDY, 7),
    e(b'P', "phantom", 8, 3, 120, &[(4, 4)], INVISIBLE, 18),
    e(b'Q', "quagga", 3, 3, 15, &[(1, 5), (1, 5)], MEAN, 11),
    e(
        b'R',
        "rattlesnake",
        2,
        3,
        9,
        &[(1, 6)],
        REDUCE_STR | MEAN,
        6,
    ),
    e(b'S', "snake", 1, 5, 2, &[(1, 3)], MEAN, 3),
    e(
        b'T',
        "troll",
        6,
        4,
        120,
        &[(1, 8), (1, 8), (2, 6)],
        MEAN | REGENERATE,
        16,
    ),
    e(
        b'U',
        "urvile",
        7,
        -2,
        190,
        &[(1, 9), (1, 9), (2, 9)],
        MEAN,
        20,
    ),
    e(
        b'V',
        "vampire",
        8,
        1,
        350,
        &[(1, 19)],
        MEAN | REGENERATE,
        22,
    ),
    e(b'W', "wraith", 5, 4, 55, &[(1, 6)], 0, 17),
    e(b'X', "xeroc", 7, 7, 100, &[(4, 4)], 0, 19),
    e(b'Y', "yeti", 4, 6, 50, &[(1, 6), (1, 6)], 0, 14),
    e(b'Z', "zombie", 2, 8, 6, &[(1, 8)], MEAN, 8),
];

/// A builtin armour: (name, defence).
pub(crate) const ARMORS: [(&str, i32); 8] = [
    ("leather armor", 2),
    ("ring mail", 3),
    ("studded leather armor", 3),
    ("scale mail", 4),
    ("chain mail", 5),
    ("splint mail", 6),
    ("banded mail", 6),
    ("plate mail", 7),
];

/// A builtin weapon: (name, wield dice (times, max)).
pub(crate) const WEAPONS: [(&str, (u32, u32)); 9] = [
    ("mace", (2, 4)),
    ("long sword", (3, 4)),
    ("short bow", (1, 1)),
    ("arrow", (1, 1)),
    ("dagger", (1, 6)),
    ("two handed sword", (4, 4)),
    ("dart", (1, 1)),
    ("shuriken", (1, 2)),
    ("spear", (2, 3)),
];

/// The original's `init_num` of each builtin weapon, half-open, in [`WEAPONS`] order: how
/// many a generated stack holds. Only its width matters here: the original draws it once per
/// starting weapon from the item stream (`"seeding": "original"`).
pub(crate) const WEAPON_COUNTS: [(u32, u32); 9] = [
    (1, 2),
    (1, 2),
    (1, 2),
    (8, 17),
    (2, 7),
    (1, 2),
    (8, 17),
    (8, 17),
    (8, 17),
];

/// Whether two item names match: case-insensitive, with spaces, `-` and `_` ignored, and
/// `bow` standing for `short bow` (the original's default inventory says `bow`).
pub(crate) fn same_item_name(a: &str, b: &str) -> bool {
    let alias = |s: &str| {
        let n = normalize(s);
        if n == "bow" {
            "shortbow".to_string()
        } else {
            n
        }
    };
    alias(a) == alias(b)
}

fn normalize(s: &str) -> String {
    s.chars()
        .filter(|c| !matches!(c, ' ' | '-' | '_'))
        .flat_map(|c| c.to_lowercase())
        .collect()
}
