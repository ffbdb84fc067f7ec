//! Worker and helper binary of the end-to-end tests.
//!
//! * `e2e_worker worker <worker args>`: a pool worker with the default env registry; it exits
//!   at once (code 3) while a file named `die-at-start` (every worker) or `die-at-start.K`
//!   (worker K) lies beside its `--config` file, so a test can make every restart fail.
//! * `e2e_worker hold-pool <num_workers>`: build a pool of test envs (workers spawned from this
//!   binary), print `pids <pid> <pid> ...` and the pool name, then sleep until killed. Used to
//!   check that workers die with a killed supervisor.

use std::io::Write;

use rogue_gym_pool::{EnvRegistry, Pool, PoolConfig, WorkerCommand, worker_main};

/// The marker file that makes workers exit at start (see the crate doc).
const DIE_AT_START: &str = "die-at-start";

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("worker") => {
            let arg = |name: &str| args.iter().skip_while(|a| *a != name).nth(1);
            let index = arg("--index").map_or("", String::as_str);
            if let Some(dir) = arg("--config").and_then(|c| std::path::Path::new(c).parent())
                && (dir.join(DIE_AT_START).exists()
                    || dir.join(format!("{DIE_AT_START}.{index}")).exists())
            {
                eprintln!("e2e_worker: {DIE_AT_START} is set, exiting at start");
                std::process::exit(3);
            }
            std::process::exit(worker_main(&args[1..], &EnvRegistry::with_defaults()))
        }
        Some("hold-pool") => {
            let workers: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(2);
            let base = args.get(2).map(std::path::PathBuf::from);
            let cmd = WorkerCommand::current_exe(&["worker"]).expect("current exe");
            let mut cfg = PoolConfig::new(
                serde_json::json!({"kind": "test"}),
                workers * 2,
                workers,
                cmd,
            );
            if let Some(b) = base {
                cfg.runtime_dir = Some(b);
            }
            let pool = match Pool::new(cfg, &EnvRegistry::with_defaults()) {
                Ok(p) => p,
                Err(e) => {
                    eprintln!("hold-pool: {e}");
                    std::process::exit(1);
                }
            };
            let pids: Vec<String> = pool.worker_pids().iter().map(u32::to_string).collect();
            println!("pool {}", pool.id().name());
            println!("pids {}", pids.join(" "));
            let _ = std::io::stdout().flush();
            loop {
                std::thread::sleep(std::time::Duration::from_secs(1));
            }
        }
        _ => {
            eprintln!(
                "usage: e2e_worker worker <args> | e2e_worker hold-pool <num_workers> [runtime_dir]"
            );
            std::process::exit(2);
        }
    }
}
