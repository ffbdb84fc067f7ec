//! The `rogue-gym` command-line tool: play in the terminal, replay an action log, and
//! benchmark the engine and the pool. It lives in its own crate so that the libraries carry no
//! CLI dependencies (clap, crossterm). Each subcommand lives in its own module; adding one is a variant in
//! [`Cmd`] plus an arm in `main`.

mod action_log;
mod bench;
mod dump;
mod play;
mod pool_bench;
mod replay;
mod terminal;
mod worker;

use std::path::Path;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use rogue_gym_engine::GameConfig;

/// Rogue-Gym: a roguelike benchmark for generalization in reinforcement learning.
#[derive(Debug, Parser)]
#[command(name = "rogue-gym", version, about)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Debug, Subcommand)]
enum Cmd {
    /// Play in the terminal (vi keys; q quits).
    Play(play::Args),
    /// Play back an action log saved by `play --save`.
    Replay(replay::Args),
    /// Measure engine steps per second.
    Bench(bench::Args),
    /// Write the floors of a range of seeds as JSON lines (the dungeon oracle's format).
    Dump(dump::Args),
    /// Benchmark the multi-process pool against the raw single-process loop.
    PoolBench(pool_bench::Args),
    /// Run a pool worker (spawned by the pool's supervisor; not for direct use).
    Worker(worker::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.cmd {
        Cmd::Play(args) => play::run(args),
        Cmd::Replay(args) => replay::run(args),
        Cmd::Bench(args) => bench::run(args),
        Cmd::Dump(args) => dump::run(args),
        Cmd::PoolBench(args) => std::process::exit(pool_bench::run(args)),
        Cmd::Worker(args) => std::process::exit(worker::run(args)),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(msg) => {
            eprintln!("error: {msg}");
            ExitCode::FAILURE
        }
    }
}

/// Reads and validates a config file, or returns `default` when no path is given.
/// Errors are messages naming the file and the offending key.
pub(crate) fn load_config(path: Option<&Path>, default: GameConfig) -> Result<GameConfig, String> {
    let Some(path) = path else { return Ok(default) };
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read config {}: {e}", path.display()))?;
    GameConfig::from_json(&text).map_err(|e| format!("config {}: {e}", path.display()))
}
