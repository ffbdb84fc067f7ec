//! The uniform random agent on 500-step episodes of three configs (the figures docs/rules.md
//! quotes): mean gold, mean final floor and the share of episodes that died, over 5,000
//! episodes each (seeds 0..5000, actions from one splitmix64 stream).
//!
//!     cargo run --release -p rogue-gym-engine --example random_agent

use rogue_gym_engine::{Action, EpisodeConfig, Game, GameConfig, splitmix64};

fn main() {
    println!("| config | mean gold | mean final floor | died |");
    println!("|---|---:|---:|---:|");
    for (name, cfg) in [
        ("paper (32x16, 2x2, no monsters)", GameConfig::paper()),
        (
            "80x24, no monsters",
            GameConfig {
                enemies: rogue_gym_engine::config::EnemiesConfig {
                    enemies: vec![],
                    ..Default::default()
                },
                ..GameConfig::default()
            },
        ),
        ("80x24, all monsters", GameConfig::default()),
    ] {
        let mut g = Game::new(
            &cfg,
            EpisodeConfig {
                max_steps: 500,
                stair_reward: 50.0,
            },
        )
        .expect("a built-in config");
        let (mut gold, mut level, mut deaths) = (0u64, 0u64, 0u64);
        let episodes = 5000u64;
        let mut state = 1u64;
        for e in 0..episodes {
            g.reset(e);
            loop {
                state = splitmix64(state);
                let r = g.step(Action::ALL[(state % 11) as usize]);
                if r.terminated || r.truncated {
                    break;
                }
            }
            gold += u64::from(g.info().gold);
            level += u64::from(g.info().floor);
            deaths += u64::from(g.info().died);
        }
        let n = episodes as f64;
        println!(
            "| {name} | {:.2} | {:.3} | {:.1}% |",
            gold as f64 / n,
            level as f64 / n,
            100.0 * deaths as f64 / n
        );
    }
}
