//! Generation invariants and statistics against docs/rules.md §12 (the original, measured over
//! 20k floors). Each test generates >= 2,000 floors; tolerances are stated next to each check.
#![allow(clippy::needless_range_loop)]

use crate::config::EnemiesConfig;
use crate::dungeon::{RoomKind, Surface, flag};
use crate::geometry::Dir;
use crate::*;

/// A game whose current floor is floor `level` of `seed`.
fn floor_game(g: &mut Game, seed: u64, level: u32) {
    g.reset(seed);
    if level > 1 {
        g.level = level - 1;
        g.new_level();
    }
}

#[derive(Default, Debug)]
struct Stats {
    floors: f64,
    gone: f64,
    normal: f64,
    maze: f64,
    dark: f64,
    gold_piles: f64,
    gold_total: f64,
    doors: f64,
    secret_doors: f64,
    hidden_passages: f64,
    passages: f64,
    bfs_sum: f64,
    bfs_n: f64,
}

impl Stats {
    fn mean(&self, v: f64) -> f64 {
        v / self.floors
    }
}

/// BFS with the player's move rule from the start; steps to the stairs if reachable.
fn bfs_to_stairs(g: &Game) -> Option<u32> {
    let n = g.floor.surface.len();
    let mut dist = vec![u32::MAX; n];
    let mut queue = std::collections::VecDeque::new();
    dist[g.player.pos] = 0;
    queue.push_back(g.player.pos);
    while let Some(c) = queue.pop_front() {
        if c == g.floor.stairs {
            return Some(dist[c]);
        }
        for d in Dir::ALL {
            if let Some(t) = g.can_move(c, d)
                && dist[t] == u32::MAX
            {
                dist[t] = dist[c] + 1;
                queue.push_back(t);
            }
        }
    }
    None
}

/// Checks the invariants of the current floor and adds it to the statistics.
fn check_and_count(g: &Game, stats: &mut Stats) {
    let f = &g.floor;
    let (w, h) = (f.w, f.h);
    // Every walkable cell (hidden features counted as found) is 4-connected to the start.
    let n = f.surface.len();
    let mut seen = vec![false; n];
    let mut stack = vec![g.player.pos];
    seen[g.player.pos] = true;
    while let Some(c) = stack.pop() {
        let (x, y) = f.xy(c);
        for (dx, dy) in [(0, -1), (0, 1), (-1, 0), (1, 0)] {
            let (nx, ny) = (x + dx, y + dy);
            if f.in_area(nx, ny) {
                let i = f.idx(nx, ny);
                if !seen[i] && f.walkable_unhidden(i) {
                    seen[i] = true;
                    stack.push(i);
                }
            }
        }
    }
    for i in 0..n {
        let (x, y) = f.xy(i);
        if f.walkable_unhidden(i) {
            assert!(
                seen[i],
                "cell ({x},{y}) is cut off (seed {})\n{}",
                g.seed,
                g.screen_string()
            );
            assert!(y >= 1 && y < h - 1 && x < w);
        }
    }
    assert!(seen[f.stairs], "stairs reachable before hiding");
    assert_eq!(f.surface[f.stairs], Surface::Stair);
    assert!(f.surface[g.player.pos].walkable());
    assert_ne!(
        g.player.pos, f.stairs,
        "the player never starts on the stairs"
    );
    assert_eq!(f.gold[g.player.pos], 0, "the player never starts on gold");
    // Rooms: sizes, inside their slot, never touching the slot's last column or row.
    let min = g.cfg.dungeon.min_room_size;
    for r in &f.rooms {
        assert!(r.rect.x0 >= r.slot.x0 && r.rect.y0 >= r.slot.y0);
        match r.kind {
            RoomKind::Normal => {
                assert!(r.rect.w() >= min.x && r.rect.h() >= min.y);
                assert!(
                    r.rect.x1 < r.slot.x1 && r.rect.y1 < r.slot.y1,
                    "gap to the next slot"
                );
                assert!((r.rect.w() - 2) * (r.rect.h() - 2) >= 4);
            }
            RoomKind::Maze => assert!(r.rect.x1 == r.slot.x1 - 1 && r.rect.y1 == r.slot.y1 - 1),
            RoomKind::Gone => assert!(r.slot.contains(r.rect.x0, r.rect.y0)),
        }
    }
    stats.floors += 1.0;
    for r in &f.rooms {
        match r.kind {
            RoomKind::Gone => stats.gone += 1.0,
            RoomKind::Normal => stats.normal += 1.0,
            RoomKind::Maze => stats.maze += 1.0,
        }
        if r.kind != RoomKind::Gone && r.dark {
            stats.dark += 1.0;
        }
    }
    for i in 0..n {
        if f.gold[i] > 0 {
            stats.gold_piles += 1.0;
            stats.gold_total += f64::from(f.gold[i]);
        }
        let fl = f.flags[i];
        if fl & flag::DOOR != 0 {
            stats.doors += 1.0;
        }
        if fl & flag::LOCKED != 0 {
            stats.secret_doors += 1.0;
        }
        if fl & flag::HIDDEN != 0 {
            stats.hidden_passages += 1.0;
        }
        if fl & flag::HIDDEN != 0 || f.surface[i] == Surface::Passage {
            stats.passages += 1.0;
        }
    }
    if let Some(d) = bfs_to_stairs(g) {
        stats.bfs_sum += f64::from(d);
        stats.bfs_n += 1.0;
    }
}

fn collect(cfg: &GameConfig, level: u32, floors: u64) -> Stats {
    let mut g = Game::new(cfg, EpisodeConfig::default()).unwrap();
    let mut stats = Stats::default();
    for seed in 0..floors {
        floor_game(&mut g, seed * 7919 + u64::from(level), level);
        check_and_count(&g, &mut stats);
    }
    stats
}

/// `|got - want| <= tol`, with a readable message.
fn near(name: &str, got: f64, want: f64, tol: f64) {
    assert!(
        (got - want).abs() <= tol,
        "{name}: got {got:.3}, want {want} +- {tol}"
    );
}

fn no_enemies(cfg: GameConfig) -> GameConfig {
    GameConfig {
        enemies: EnemiesConfig {
            enemies: vec![],
            ..Default::default()
        },
        ..cfg
    }
}

#[test]
fn paper_level_1() {
    let s = collect(&GameConfig::paper(), 1, 3000);
    eprintln!("{s:?}");
    near("gone rooms", s.mean(s.gone), 1.5, 0.1);
    near("normal rooms", s.mean(s.normal), 2.46, 0.1);
    near("dark rooms", s.mean(s.dark), 0.25, 0.05);
    near("gold piles", s.mean(s.gold_piles), 1.24, 0.08);
    near("mean pile", s.gold_total / s.gold_piles, 31.6, 2.0);
    near("doors", s.mean(s.doors), 4.44, 4.44 * 0.15);
    near("secret doors", s.mean(s.secret_doors), 0.09, 0.04);
    near(
        "hidden passage cells",
        s.mean(s.hidden_passages),
        0.09,
        0.05,
    );
    near("passage cells", s.mean(s.passages), 36.0, 36.0 * 0.15);
    near("BFS start-stairs", s.bfs_sum / s.bfs_n, 11.6, 11.6 * 0.15);
    near("stairs reachable", s.bfs_n / s.floors, 0.981, 0.03);
}

#[test]
fn paper_level_10() {
    let s = collect(&GameConfig::paper(), 10, 2000);
    eprintln!("{s:?}");
    near("gone rooms", s.mean(s.gone), 1.5, 0.1);
    near("dark rooms", s.mean(s.dark), 2.50, 0.1);
    near("maze rooms", s.mean(s.maze), 0.166, 0.05);
    near("gold piles", s.mean(s.gold_piles), 1.25, 0.08);
    near("mean pile", s.gold_total / s.gold_piles, 76.3, 4.0);
    near("secret doors", s.mean(s.secret_doors), 0.85, 0.85 * 0.2);
    near(
        "hidden passage cells",
        s.mean(s.hidden_passages),
        1.06,
        1.06 * 0.35,
    );
    near("BFS start-stairs", s.bfs_sum / s.bfs_n, 9.6, 9.6 * 0.15);
}

#[test]
fn default_80x24_level_1() {
    let s = collect(&no_enemies(GameConfig::default()), 1, 2000);
    eprintln!("{s:?}");
    near("gone rooms", s.mean(s.gone), 1.5, 0.1);
    near("normal rooms", s.mean(s.normal), 7.45, 0.15);
    near("dark rooms", s.mean(s.dark), 0.75, 0.1);
    near("gold piles", s.mean(s.gold_piles), 3.75, 0.15);
    near("doors", s.mean(s.doors), 15.2, 15.2 * 0.15);
    near("passage cells", s.mean(s.passages), 119.0, 119.0 * 0.15);
    near("BFS start-stairs", s.bfs_sum / s.bfs_n, 45.0, 45.0 * 0.15);
}

#[test]
fn default_80x24_level_10() {
    let s = collect(&no_enemies(GameConfig::default()), 10, 2000);
    eprintln!("{s:?}");
    near("maze rooms", s.mean(s.maze), 0.50, 0.08);
    near("dark rooms", s.mean(s.dark), 7.52, 0.15);
    near("mean pile", s.gold_total / s.gold_piles, 76.6, 3.0);
    near("secret doors", s.mean(s.secret_doors), 2.88, 2.88 * 0.2);
    near(
        "hidden passage cells",
        s.mean(s.hidden_passages),
        3.91,
        3.91 * 0.35,
    );
    near("BFS start-stairs", s.bfs_sum / s.bfs_n, 29.9, 29.9 * 0.15);
}
