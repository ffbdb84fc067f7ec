//! Floor records: a floor as generated (not as seen), in the record format of the original's
//! dungeon oracle: the map, the start, the stairs, the gold, the rooms and the hidden features.
//! `rogue-gym dump` writes them, one JSON line per seed and floor.
//!
//! ```
//! use rogue_gym_engine::{GameConfig, floor_records};
//! let floors = floor_records(&GameConfig::paper(), 1000, 3).unwrap();
//! assert_eq!(floors.len(), 3);
//! let f = &floors[0];
//! assert_eq!((f.floor, f.reached_by.as_str()), (1, "start"));
//! assert_eq!(f.map[f.stairs[1] as usize].as_bytes()[f.stairs[0] as usize], b'%');
//! ```

use serde::{Deserialize, Serialize};

use crate::config::{ConfigError, GameConfig};
use crate::dungeon::{RoomKind, flag};
use crate::game::{EpisodeConfig, Game};

/// One floor of one seed. Coordinates are `[x, y]`; row 0 is the message line.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FloorRecord {
    /// The episode seed.
    pub seed: u64,
    /// The floor (1 = the first).
    pub floor: u32,
    /// Screen width.
    pub width: i32,
    /// Screen height.
    pub height: i32,
    /// The map as generated, `height` strings of `width` bytes: `-` `|` walls, `.` floor, `+`
    /// door, `#` passage or maze cell, `%` stairs. A secret door shows its wall, a hidden
    /// passage a blank; gold, the player and monsters are not drawn.
    pub map: Vec<String>,
    /// Where the player starts on this floor.
    pub player_start: [i32; 2],
    /// The stairs.
    pub stairs: [i32; 2],
    /// The gold piles, in cell order.
    pub gold: Vec<GoldRecord>,
    /// The rooms, in slot order (0 is the top-left slot, row by row).
    pub rooms: Vec<RoomRecord>,
    /// Door cells, secret ones included, in cell order.
    pub doors: Vec<[i32; 2]>,
    /// Hidden passage cells, in cell order.
    pub hidden_passages: Vec<[i32; 2]>,
    /// Secret ("locked") doors, in cell order.
    pub locked_doors: Vec<[i32; 2]>,
    /// `"start"` for floor 1, `"teleport"` for a floor reached by standing on the stairs of
    /// the one before and descending with no other action.
    pub reached_by: String,
}

/// A gold pile.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GoldRecord {
    /// Its cell.
    pub pos: [i32; 2],
    /// Its amount.
    pub amount: u32,
    /// Always `"Gold"`.
    pub kind: String,
}

/// A room slot and what it holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RoomRecord {
    /// Slot id.
    pub id: usize,
    /// `"normal"`, `"maze"` or `"gone"`.
    pub kind: String,
    /// Dark room (gone rooms count as dark).
    pub dark: bool,
    /// Got a gold pile.
    pub has_gold: bool,
    /// The slot's columns, half-open.
    pub assigned_x: [i32; 2],
    /// The slot's rows, half-open.
    pub assigned_y: [i32; 2],
    /// The room's (or maze's) columns, half-open, walls included; `None` for a gone room.
    pub range_x: Option<[i32; 2]>,
    /// The room's rows, likewise.
    pub range_y: Option<[i32; 2]>,
    /// A gone room's junction cell.
    pub gone_at: Option<[i32; 2]>,
}

impl Game {
    /// The record of the current floor, with the player's current cell as its start.
    pub fn floor_record(&self, reached_by: &str) -> FloorRecord {
        let f = &self.floor;
        let xy = |i: usize| {
            let (x, y) = f.xy(i);
            [x, y]
        };
        let cells_with = |bits: u8| -> Vec<[i32; 2]> {
            (0..f.flags.len())
                .filter(|&i| f.flags[i] & bits == bits)
                .map(xy)
                .collect()
        };
        let map = (0..f.h)
            .map(|y| {
                (0..f.w)
                    .map(|x| char::from(f.surface[f.idx(x, y)].tile()))
                    .collect()
            })
            .collect();
        let gold = (0..f.gold.len())
            .filter(|&i| f.gold[i] > 0)
            .map(|i| GoldRecord {
                pos: xy(i),
                amount: f.gold[i],
                kind: "Gold".into(),
            })
            .collect();
        let rooms = f
            .rooms
            .iter()
            .enumerate()
            .map(|(id, r)| {
                let gone = r.kind == RoomKind::Gone;
                RoomRecord {
                    id,
                    kind: match r.kind {
                        RoomKind::Gone => "gone",
                        RoomKind::Normal => "normal",
                        RoomKind::Maze => "maze",
                    }
                    .into(),
                    dark: r.dark,
                    has_gold: r.has_gold,
                    assigned_x: [r.slot.x0, r.slot.x1],
                    assigned_y: [r.slot.y0, r.slot.y1],
                    range_x: (!gone).then_some([r.rect.x0, r.rect.x1]),
                    range_y: (!gone).then_some([r.rect.y0, r.rect.y1]),
                    gone_at: gone.then_some([r.rect.x0, r.rect.y0]),
                }
            })
            .collect();
        FloorRecord {
            seed: self.seed,
            floor: self.level,
            width: f.w,
            height: f.h,
            map,
            player_start: xy(self.player.pos),
            stairs: xy(f.stairs),
            gold,
            rooms,
            doors: cells_with(flag::DOOR),
            hidden_passages: cells_with(flag::HIDDEN),
            locked_doors: cells_with(flag::LOCKED),
            reached_by: reached_by.into(),
        }
    }
}

/// The records of floors `1..=floors` of `seed` under `config`: floor 1 as the game starts,
/// each later floor reached by descending from the stairs of the one before.
///
/// Fails only if `config` is invalid.
pub fn floor_records(
    config: &GameConfig,
    seed: u64,
    floors: u32,
) -> Result<Vec<FloorRecord>, ConfigError> {
    let mut game = Game::new(config, EpisodeConfig::default())?;
    game.reset(seed);
    let mut out = Vec::with_capacity(floors as usize);
    for k in 1..=floors {
        if k > 1 {
            game.new_level();
        }
        out.push(game.floor_record(if k == 1 { "start" } else { "teleport" }));
    }
    Ok(out)
}
