//! `rogue-gym bench`: engine steps per second on one thread: random actions from a seeded
//! rng, the observation encoded every step, 500-step episodes with resets included.

use std::path::PathBuf;
use std::time::Instant;

use rogue_gym_engine::{
    Action, Dtype, Encoding, EpisodeConfig, Game, GameConfig, ObsBufMut, ObsSpec, splitmix64,
};

/// Arguments of `bench`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Game config (JSON). Default: the paper's config.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Steps to run.
    #[arg(long, default_value_t = 5_000_000)]
    steps: u64,
    /// Observation encoding: symbol_onehot, symbol_index, gray, ascii or status.
    #[arg(long, default_value = "symbol_onehot", value_parser = parse_encoding)]
    encoding: Encoding,
    /// Observation dtype: u8 or f32.
    #[arg(long, default_value = "u8", value_parser = parse_dtype)]
    dtype: Dtype,
    /// Episode length (steps) before a reset.
    #[arg(long, default_value_t = 500)]
    max_steps: u32,
    /// Seed of the action rng (episode seeds cycle through the config's seed range).
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

fn parse_encoding(s: &str) -> Result<Encoding, String> {
    s.parse().map_err(|e| format!("{e}"))
}

fn parse_dtype(s: &str) -> Result<Dtype, String> {
    s.parse().map_err(|e| format!("{e}"))
}

pub(crate) fn run(args: Args) -> Result<(), String> {
    let config = crate::load_config(args.config.as_deref(), GameConfig::paper())?;
    let mut game = Game::new(
        &config,
        EpisodeConfig {
            max_steps: args.max_steps,
            ..EpisodeConfig::default()
        },
    )
    .map_err(|e| e.to_string())?;
    let spec = ObsSpec {
        encoding: args.encoding,
        dtype: args.dtype,
        ..ObsSpec::paper()
    };
    let n: usize = game.observation_shape(&spec).iter().product();
    let mut buf_u8 = vec![0u8; if args.dtype == Dtype::U8 { n } else { 0 }];
    let mut buf_f32 = vec![0f32; if args.dtype == Dtype::F32 { n } else { 0 }];
    let mut state = args.seed;
    let mut episode = 0u64;
    game.reset(config.seed_for_episode(episode));
    let (mut episodes, mut reward) = (0u64, 0f64);
    let start = Instant::now();
    for _ in 0..args.steps {
        state = splitmix64(state);
        let r = game.step(Action::ALL[(state % 11) as usize]);
        reward += f64::from(r.reward);
        let out = match args.dtype {
            Dtype::U8 => ObsBufMut::U8(&mut buf_u8),
            Dtype::F32 => ObsBufMut::F32(&mut buf_f32),
        };
        game.write_obs(&spec, out).map_err(|e| e.to_string())?;
        if r.terminated || r.truncated {
            episodes += 1;
            episode += 1;
            game.reset(config.seed_for_episode(episode));
        }
    }
    let secs = start.elapsed().as_secs_f64();
    let shape = game.observation_shape(&spec);
    println!(
        "{} steps in {:.3} s: {:.0} steps/s ({}x{}, encoding {} {} {:?}, {} episodes, mean reward {:.2})",
        args.steps,
        secs,
        args.steps as f64 / secs.max(1e-9),
        config.width,
        config.height,
        args.encoding,
        args.dtype,
        shape,
        episodes,
        if episodes > 0 {
            reward / episodes as f64
        } else {
            reward
        }
    );
    Ok(())
}
