//! Diagnostics (ignored) for the random agent's gap to docs/rules.md §12: how much of it comes
//! from the original's raw seeding of floor 1 (see `crate::rng::legacy`). Run with
//! `cargo test --release -p rogue-gym-engine --lib random_agent -- --ignored --nocapture`.

use crate::config::EnemiesConfig;
use crate::dungeon::RoomKind;
use crate::rng::legacy;
use crate::*;

/// Mean gold, mean final floor, death rate and P(stairs in the start room) of the uniform
/// random agent over 500-step episodes of seeds `seeds`.
fn baseline(cfg: &GameConfig, raw_seeding: u8, seeds: std::ops::Range<u64>) -> [f64; 4] {
    legacy::set(raw_seeding);
    let episode = EpisodeConfig {
        max_steps: 500,
        stair_reward: 50.0,
    };
    let mut g = Game::new(cfg, episode).unwrap();
    let (mut gold, mut floor, mut died, mut same) = (0u64, 0u64, 0u64, 0u64);
    let mut state = 1u64;
    let n = seeds.end - seeds.start;
    for seed in seeds {
        g.reset(seed);
        same += u64::from(g.floor.room_at(g.player.pos) == g.floor.room_at(g.floor.stairs));
        loop {
            state = splitmix64(state);
            let r = g.step(Action::ALL[(state % 11) as usize]);
            if r.terminated || r.truncated {
                break;
            }
        }
        let info = g.info();
        gold += u64::from(info.gold);
        floor += u64::from(info.floor);
        died += u64::from(info.died);
    }
    legacy::set(0);
    let n = n as f64;
    [
        gold as f64 / n,
        floor as f64 / n,
        died as f64 / n,
        same as f64 / n,
    ]
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

/// Floor-1 layout statistics: mean gone rooms, P(slot 0 is a maze), mean gold piles, mean
/// pile size.
fn floor1(cfg: &GameConfig, raw_seeding: u8, seeds: std::ops::Range<u64>) -> [f64; 4] {
    legacy::set(raw_seeding);
    let mut g = Game::new(cfg, EpisodeConfig::default()).unwrap();
    let (mut gone, mut maze0, mut piles, mut total) = (0u64, 0u64, 0u64, 0u64);
    let n = (seeds.end - seeds.start) as f64;
    for seed in seeds {
        g.reset(seed);
        let f = &g.floor;
        gone += f.rooms.iter().filter(|r| r.kind == RoomKind::Gone).count() as u64;
        maze0 += u64::from(f.rooms[0].kind == RoomKind::Maze);
        for &v in f.gold.iter().filter(|&&v| v > 0) {
            piles += 1;
            total += u64::from(v);
        }
    }
    legacy::set(0);
    [
        gone as f64 / n,
        maze0 as f64 / n,
        piles as f64 / n,
        total as f64 / piles.max(1) as f64,
    ]
}

/// The random agent with our seeding and with the original's raw seeding of floor 1, on
/// 5,000 distinct seeds and on the paper's test seeds 1000..2000 (five episodes each).
#[test]
#[ignore]
fn random_agent_raw_seeding() {
    let configs = [
        ("paper", GameConfig::paper()),
        ("80x24 no monsters", no_enemies(GameConfig::default())),
        ("80x24 monsters", GameConfig::default()),
    ];
    for (name, cfg) in &configs {
        for (what, seeds, repeats) in [
            ("seeds 0..5000", 0..5000, 1),
            ("seeds 1000..2000 x5", 1000..2000, 5),
        ] {
            for (raw, label) in [
                (0, "none"),
                (legacy::ALL, "all"),
                (legacy::DUNGEON, "dungeon"),
                (legacy::ITEMS, "items"),
                (legacy::DUNGEON | legacy::ITEMS, "dungeon+items"),
            ] {
                let mut m = [0.0; 4];
                for _ in 0..repeats {
                    let r = baseline(cfg, raw, seeds.clone());
                    for (a, b) in m.iter_mut().zip(r) {
                        *a += b / f64::from(repeats);
                    }
                }
                let [gold, floor, died, same] = m;
                let [gone, maze0, piles, pile] = floor1(cfg, raw, seeds.clone());
                eprintln!(
                    "{name:18} {what:19} raw-seeded {label:13}: gold {gold:5.2}  floor {floor:.3}  \
                     died {:4.1}%  | floor 1: stairs in start room {same:.3}, gone rooms \
                     {gone:.2}, slot 0 maze {maze0:.3}, gold piles {piles:.2}, mean pile {pile:.1}",
                    100.0 * died
                );
            }
        }
    }
}

/// Floor 1 of the spec's appendix-A seeds under raw seeding: like the original's maps there,
/// slot 0 is a maze and no room is gone (the layouts differ in detail: see `rng::legacy`).
#[test]
#[ignore]
fn print_raw_seeded_maps() {
    for (cfg, seed) in [
        (GameConfig::paper(), 3u64),
        (no_enemies(GameConfig::default()), 7),
    ] {
        legacy::set(legacy::ALL);
        let cfg = GameConfig {
            hide_dungeon: false,
            ..cfg
        };
        let mut g = Game::new(&cfg, EpisodeConfig::default()).unwrap();
        g.reset(seed);
        legacy::set(0);
        eprintln!("seed {seed}:\n{}", g.screen_string());
    }
}
