//! The `rogue-gym` command-line tool.

use clap::{Parser, Subcommand};

mod pool_bench;
mod worker;

/// Rogue-Gym command-line tool.
#[derive(Parser)]
#[command(name = "rogue-gym", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Benchmark the multi-process pool against the raw single-process loop.
    PoolBench(pool_bench::Args),
    /// Run a pool worker (spawned by the pool's supervisor; not for direct use).
    Worker(worker::Args),
}

fn main() {
    let cli = Cli::parse();
    let code = match cli.command {
        Cmd::PoolBench(a) => pool_bench::run(a),
        Cmd::Worker(a) => worker::run(a),
    };
    std::process::exit(code);
}
