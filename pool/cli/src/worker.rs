//! `rogue-gym worker ...`: a pool worker (the supervisor spawns it; see
//! `rogue_gym_pool::worker_main` for the arguments).

use rogue_gym_pool::{EnvRegistry, worker_main};

/// Arguments are passed through to the worker loop unchanged.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// `--config <file> --index <k> --generation <g> --ppid <pid>`
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    args: Vec<String>,
}

/// Run the worker; returns the exit code.
pub fn run(a: Args) -> i32 {
    worker_main(&a.args, &EnvRegistry::with_defaults())
}
