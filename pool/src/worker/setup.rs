//! A worker's start: its command line, its config file (read only from a private file in a
//! private directory), the core it is pinned to, and a successor's wait for its go.

use std::path::PathBuf;
use std::time::Duration;

use rogue_gym_ipc::PoolId;

use super::WorkerError;
use crate::wire::{SHARED_FDS, WorkerConfig, successor_go};

/// The worker's command line (see [`super::worker_main`]).
pub(super) struct Args {
    pub(super) config: PathBuf,
    pub(super) index: usize,
    pub(super) generation: u64,
    pub(super) ppid: i32,
    /// A planned replacement ([`crate::wire::successor_marker`]): build the envs while the
    /// worker it replaces still serves, say so, then take over its ports once they are free.
    pub(super) successor: bool,
    /// The descriptors of the pool's buffers ([`crate::wire::SHARED_FDS`] order).
    pub(super) shared_fds: Vec<i32>,
}

/// Parse the worker's command line; an error says which argument is missing or bad.
pub(super) fn parse_args(args: &[String]) -> Result<Args, String> {
    let mut config = None;
    let mut index = None;
    let mut generation = 0u64;
    let mut ppid = None;
    let mut successor = false;
    let mut shared_fds = Vec::new();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut val = |name: &str| {
            it.next()
                .cloned()
                .ok_or_else(|| format!("{name} needs a value"))
        };
        match a.as_str() {
            "--config" => config = Some(PathBuf::from(val("--config")?)),
            "--index" => {
                index = Some(
                    val("--index")?
                        .parse()
                        .map_err(|e| format!("--index: {e}"))?,
                )
            }
            "--generation" => {
                generation = val("--generation")?
                    .parse()
                    .map_err(|e| format!("--generation: {e}"))?
            }
            "--ppid" => ppid = Some(val("--ppid")?.parse().map_err(|e| format!("--ppid: {e}"))?),
            "--successor" => successor = true,
            "--shared-fds" => {
                shared_fds = val("--shared-fds")?
                    .split(',')
                    .map(|f| f.parse::<i32>().map_err(|e| format!("--shared-fds: {e}")))
                    .collect::<Result<_, _>>()?;
            }
            other => return Err(format!("unexpected argument {other:?}")),
        }
    }
    Ok(Args {
        config: config.ok_or("missing --config <file>")?,
        index: index.ok_or("missing --index <worker index>")?,
        generation,
        ppid: ppid.ok_or("missing --ppid <supervisor pid>")?,
        successor,
        shared_fds: (shared_fds.len() == SHARED_FDS.len())
            .then_some(shared_fds)
            .ok_or("missing --shared-fds <batch>,<books>,<stats>")?,
    })
}

/// Wait for the supervisor's word that the worker this successor replaces is gone
/// ([`successor_go`]), while the supervisor lives: a successor that is not needed is killed.
pub(super) fn wait_for_go(id: &PoolId, a: &Args) -> Result<(), WorkerError> {
    let go = successor_go(id, a.index, a.generation);
    while !go.exists() {
        if nix::unistd::getppid().as_raw() != a.ppid {
            return Err(WorkerError::ParentGone(a.ppid));
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let _ = std::fs::remove_file(&go);
    Ok(())
}

/// Pin this process to core `core` (the supervisor chose it: `WorkerConfig::cpu_cores`).
pub(super) fn pin_to_core(core: usize) -> Result<usize, nix::Error> {
    use nix::sched::{CpuSet, sched_setaffinity};
    let mut one = CpuSet::new();
    one.set(core)?;
    sched_setaffinity(nix::unistd::Pid::from_raw(0), &one)?;
    Ok(core)
}

/// Read the worker's config: a private file of this user in a private directory of this user
/// (the pool's, inside its verified runtime directory), so that no one else can have written
/// what the worker builds its envs from (hosted envs unpickle it).
pub(super) fn read_config(path: &std::path::Path) -> Result<WorkerConfig, String> {
    let dir = path.parent().unwrap_or(std::path::Path::new("/"));
    let meta = std::fs::symlink_metadata(dir)
        .map_err(|e| format!("cannot inspect {}: {e}", dir.display()))?;
    rogue_gym_ipc::private::check_private(dir, &meta, true).map_err(|e| e.to_string())?;
    let data = rogue_gym_ipc::private::read_private_file(path)
        .map_err(|e| format!("cannot read worker config: {e}"))?;
    serde_json::from_slice(&data).map_err(|e| format!("bad worker config: {e}"))
}
