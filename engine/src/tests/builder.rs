//! A test-only constructor: lays out a floor from ASCII art.
//!
//! Tiles: `-` `|` walls, `.` floor, `#` passage, `+` door, `%` stairs, `*` gold (10),
//! `,` amulet, `@` player (on floor), `~` hidden passage, `&` secret door (in a wall),
//! `A`..`Z` an awake monster of that letter (on floor; the config must enable it).
//! The whole dungeon area is one room slot whose room is the bounding box of the walls.

use crate::actors::Enemy;
use crate::dungeon::floor::Room;
use crate::dungeon::{Floor, RoomKind, Surface, flag};
use crate::geometry::Rect;
use crate::{EpisodeConfig, Game, GameConfig};

impl Game {
    /// Builds a game on a hand-made floor 1. `rows` are dungeon rows 1.. (row 0 is the
    /// message line); missing cells are rock.
    pub(crate) fn from_layout(
        cfg: &GameConfig,
        episode: EpisodeConfig,
        rows: &[&str],
        dark: bool,
    ) -> Game {
        let mut g = Game::new(cfg, episode).expect("valid config");
        let (w, h) = (cfg.width, cfg.height);
        let mut floor = Floor::default();
        floor.clear(w, h);
        for e in &g.enemies {
            g.enemy_at[e.pos] = 0;
        }
        g.enemies.clear();
        g.enemy_at.fill(0);
        let mut player = None;
        let mut walls = Rect {
            x0: i32::MAX,
            y0: i32::MAX,
            x1: i32::MIN,
            y1: i32::MIN,
        };
        for (r, row) in rows.iter().enumerate() {
            let y = r as i32 + 1;
            for (x, ch) in row.bytes().enumerate() {
                let x = x as i32;
                let i = floor.idx(x, y);
                let s = match ch {
                    b'-' => Surface::WallH,
                    b'|' => Surface::WallV,
                    b'&' => {
                        floor.flags[i] |= flag::LOCKED | flag::DOOR;
                        Surface::WallV
                    }
                    b'+' => {
                        floor.flags[i] |= flag::DOOR;
                        Surface::Door
                    }
                    b'#' => Surface::Passage,
                    b'~' => {
                        floor.flags[i] |= flag::HIDDEN;
                        Surface::Nothing
                    }
                    b'%' => {
                        floor.stairs = i;
                        Surface::Stair
                    }
                    b' ' => Surface::Nothing,
                    _ => Surface::Floor,
                };
                floor.surface[i] = s;
                if matches!(s, Surface::WallH | Surface::WallV | Surface::Door) {
                    walls.x0 = walls.x0.min(x);
                    walls.y0 = walls.y0.min(y);
                    walls.x1 = walls.x1.max(x + 1);
                    walls.y1 = walls.y1.max(y + 1);
                }
                if s == Surface::Floor && dark {
                    floor.flags[i] |= flag::DARK;
                }
                match ch {
                    b'*' => floor.gold[i] = 10,
                    b',' => floor.amulet = Some(i),
                    b'@' => player = Some(i),
                    b'A'..=b'Z' => {
                        let kind = g
                            .kinds
                            .iter()
                            .position(|k| k.tile == ch)
                            .expect("monster enabled") as u16;
                        g.enemies.push(Enemy {
                            kind,
                            pos: i,
                            hp: 8,
                            level: g.kinds[kind as usize].level,
                            defense: g.kinds[kind as usize].defense,
                            exp: g.kinds[kind as usize].exp,
                            awake: true,
                            alive: true,
                        });
                        g.enemy_at[i] = g.enemies.len() as u16;
                    }
                    _ => {}
                }
            }
        }
        let slot = Rect {
            x0: 0,
            y0: 1,
            x1: w,
            y1: h - 1,
        };
        let rect = if walls.x0 == i32::MAX {
            Rect {
                x0: 0,
                y0: 0,
                x1: 0,
                y1: 0,
            }
        } else {
            walls
        };
        for y in slot.y0..slot.y1 {
            for x in 0..w {
                let i = floor.idx(x, y);
                floor.slot_of[i] = 0;
                floor.zone[i] = u16::from(rect.contains(x, y));
            }
        }
        floor
            .rooms
            .push(Room::new(RoomKind::Normal, slot, rect, dark));
        g.floor = floor;
        g.player.pos = player.expect("layout has a player");
        g.player_in(g.player.pos, true);
        let n = g.ascii.len();
        g.dirty.extend((w as u32)..(n as u32 - w as u32));
        g.refresh_screen();
        g
    }

    /// The tile shown at `(x, y)`.
    pub(crate) fn tile_at(&self, x: i32, y: i32) -> u8 {
        self.ascii[(y * self.cfg.width + x) as usize]
    }
}
