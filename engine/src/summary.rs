//! Difficulty metadata of a floor: what a generalization benchmark's per-seed manifest
//! records (rooms, dark/maze/gone rooms, hidden features, gold, the walk to the stairs).
//!
//! ```
//! use rogue_gym_engine::{GameConfig, floor_summary};
//! let s = floor_summary(&GameConfig::paper(), 1000).unwrap();
//! assert_eq!(s.level, 1);
//! assert_eq!(s.rooms + s.gone_rooms, 4);
//! assert!(s.stairs_distance_unhidden.is_some());
//! ```

use serde::Serialize;

use crate::config::{ConfigError, GameConfig};
use crate::dungeon::{Floor, RoomKind, flag};
use crate::game::{EpisodeConfig, Game};
use crate::geometry::Dir;

/// Difficulty metadata of the current floor of a game (see [`Game::floor_summary`]).
///
/// Distances are shortest walks from the player's start cell to the stairs, in moves, under
/// the game's movement rule: 8 directions, the target cell walkable, and a diagonal move also
/// needs both orthogonal neighbours walkable (so no diagonal move through a doorway or around
/// a passage corner). Monsters are ignored.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct FloorSummary {
    /// The episode seed.
    pub seed: u64,
    /// The floor (1 = the first).
    pub level: u32,
    /// Real rooms: normal + maze (not gone).
    pub rooms: u32,
    /// Normal (rectangular, walled) rooms.
    pub normal_rooms: u32,
    /// Maze rooms (always dark).
    pub maze_rooms: u32,
    /// Dark real rooms, mazes included.
    pub dark_rooms: u32,
    /// Gone rooms (junction points only).
    pub gone_rooms: u32,
    /// Door cells (secret ones included).
    pub doors: u32,
    /// Secret ("locked") doors: look like walls until searched.
    pub hidden_doors: u32,
    /// Passage cells (hidden ones included).
    pub passage_cells: u32,
    /// Hidden passage cells: blank until searched.
    pub hidden_passages: u32,
    /// Gold piles on the floor.
    pub gold_piles: u32,
    /// Total gold on the floor.
    pub gold_total: u32,
    /// Shortest walk to the stairs without searching (hidden passages and secret doors are
    /// rock/wall); `None` if the stairs can only be reached by searching.
    pub stairs_distance: Option<u32>,
    /// Shortest walk to the stairs if every hidden feature were already found.
    pub stairs_distance_unhidden: Option<u32>,
}

impl Game {
    /// Difficulty metadata of the current floor, from the player's current cell.
    ///
    /// Right after [`Game::reset`] this describes floor 1 of the episode's seed as the agent
    /// starts it.
    pub fn floor_summary(&self) -> FloorSummary {
        summarize(&self.floor, self.seed, self.level, self.player.pos)
    }
}

/// The [`FloorSummary`] of floor 1 of `seed` under `config` (a fresh game, reset to `seed`).
///
/// Fails only if `config` is invalid.
pub fn floor_summary(config: &GameConfig, seed: u64) -> Result<FloorSummary, ConfigError> {
    let mut game = Game::new(config, EpisodeConfig::default())?;
    game.reset(seed);
    Ok(game.floor_summary())
}

fn summarize(floor: &Floor, seed: u64, level: u32, start: usize) -> FloorSummary {
    let mut s = FloorSummary {
        seed,
        level,
        ..FloorSummary::default()
    };
    for room in &floor.rooms {
        match room.kind {
            RoomKind::Gone => s.gone_rooms += 1,
            RoomKind::Normal => s.normal_rooms += 1,
            RoomKind::Maze => s.maze_rooms += 1,
        }
        if room.kind != RoomKind::Gone && (room.dark || room.kind == RoomKind::Maze) {
            s.dark_rooms += 1;
        }
    }
    s.rooms = s.normal_rooms + s.maze_rooms;
    for (i, &f) in floor.flags.iter().enumerate() {
        if f & flag::DOOR != 0 {
            s.doors += 1;
            if f & flag::LOCKED != 0 {
                s.hidden_doors += 1;
            }
        } else if f & flag::HIDDEN != 0 {
            s.hidden_passages += 1;
            s.passage_cells += 1;
        } else if floor.surface[i] == crate::dungeon::Surface::Passage {
            s.passage_cells += 1;
        }
        if floor.gold[i] > 0 {
            s.gold_piles += 1;
            s.gold_total += floor.gold[i];
        }
    }
    s.stairs_distance = walk(floor, start, floor.stairs, |i| floor.surface[i].walkable());
    s.stairs_distance_unhidden = walk(floor, start, floor.stairs, |i| floor.walkable_unhidden(i));
    s
}

/// Breadth-first search under the movement rule with `walkable` deciding every cell.
fn walk(floor: &Floor, from: usize, to: usize, walkable: impl Fn(usize) -> bool) -> Option<u32> {
    let n = floor.surface.len();
    if from >= n || to >= n {
        return None;
    }
    let mut dist = vec![u32::MAX; n];
    let mut queue = std::collections::VecDeque::with_capacity(n);
    dist[from] = 0;
    queue.push_back(from);
    while let Some(c) = queue.pop_front() {
        if c == to {
            return Some(dist[c]);
        }
        let (x, y) = floor.xy(c);
        for dir in Dir::ALL {
            let (dx, dy) = dir.delta();
            let (nx, ny) = (x + dx, y + dy);
            if !floor.in_area(nx, ny) {
                continue;
            }
            let t = floor.idx(nx, ny);
            if dist[t] != u32::MAX || !walkable(t) {
                continue;
            }
            if dir.is_diagonal() && !(walkable(floor.idx(nx, y)) && walkable(floor.idx(x, ny))) {
                continue;
            }
            dist[t] = dist[c] + 1;
            queue.push_back(t);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::action::Action;

    fn paper() -> GameConfig {
        let mut c = GameConfig::paper();
        c.seed_range = None;
        c
    }

    #[test]
    fn counts_are_consistent_on_many_seeds() {
        let cfg = paper();
        let mut reachable = 0;
        for seed in 0..300 {
            let s = floor_summary(&cfg, seed).unwrap();
            assert_eq!(s.seed, seed);
            assert_eq!(s.level, 1);
            assert_eq!(s.rooms + s.gone_rooms, 4, "2x2 slots");
            assert!(s.rooms >= 1);
            assert!(s.gone_rooms <= 3);
            assert!(s.dark_rooms <= s.rooms);
            assert!(s.maze_rooms <= s.dark_rooms);
            assert!(s.hidden_doors <= s.doors);
            assert!(s.hidden_passages <= s.passage_cells);
            assert!(s.gold_piles <= s.rooms);
            // Finding everything can only shorten the walk.
            let all = s
                .stairs_distance_unhidden
                .expect("stairs reachable once all is found");
            if let Some(d) = s.stairs_distance {
                assert!(all <= d);
                reachable += 1;
            }
        }
        // docs/rules.md §2.5: ~98% reachable without searching at level 1.
        assert!(reachable >= 270, "{reachable}/300 reachable");
    }

    #[test]
    fn summary_is_deterministic_and_depends_on_the_seed() {
        let cfg = GameConfig::default();
        let a: Vec<_> = (0..20).map(|s| floor_summary(&cfg, s).unwrap()).collect();
        let b: Vec<_> = (0..20).map(|s| floor_summary(&cfg, s).unwrap()).collect();
        assert_eq!(a, b);
        let distinct: std::collections::BTreeSet<_> = a
            .iter()
            .map(|s| (s.stairs_distance, s.gold_total, s.doors))
            .collect();
        assert!(distinct.len() > 5);
        for s in &a {
            assert_eq!(s.rooms + s.gone_rooms, 9, "3x3 slots");
        }
    }

    #[test]
    fn walking_the_shortest_path_is_possible() {
        // The distance is a lower bound on steps to the stairs; an empty walk (start on the
        // stairs) is 0 and moving changes the distance by at most one.
        let cfg = paper();
        let mut game = Game::new(&cfg, EpisodeConfig::default()).unwrap();
        game.reset(1234);
        let before = game.floor_summary();
        game.step(Action::Right);
        let after = game.floor_summary();
        if let (Some(a), Some(b)) = (before.stairs_distance, after.stairs_distance) {
            assert!(a.abs_diff(b) <= 1);
        }
        assert_eq!(floor_summary(&cfg, 1234).unwrap(), before);
    }

    #[test]
    fn invalid_config_is_an_error() {
        let cfg = GameConfig {
            width: 10,
            ..GameConfig::default()
        };
        assert!(floor_summary(&cfg, 0).is_err());
    }
}
