//! The worker process: steps a block of envs, each env writing its rows (observation, record,
//! infos) in the pool's batch slot its command names, and publishes one answer word per
//! command through iceoryx2.
//!
//! Entry point: [`worker_main`], called by `rogue-gym worker ...`, by the e2e test binary and by
//! the Python extension (`python -m rogue_gym.worker ...`). Arguments (after the program and its
//! leading args): `--config <file> --index <k> --generation <g> --ppid <supervisor pid>
//! --shared-fds <batch>,<books>,<stats>` (the descriptors of the pool's buffers, which the
//! supervisor keeps open across the worker's `exec`).
//!
//! The worker is set up ([`worker_main`]; its command line and config in `setup.rs`) and then
//! runs one executor (`executor.rs`): a loop that takes commands, checks each once, serves it
//! and publishes its answer. A reset or step is served
//! inline (`inline.rs`: env after env, `envs.rs`, each env's state machine in `env_state.rs`,
//! or as one [`crate::EnvBlock`], `block.rs`), or with each env on a thread of its own
//! (`concurrent.rs`, `env_threads.rs`: the pool's `env_concurrency`, the executor with
//! threads). The rows are written in `block_out.rs`, with streaming stores for large batches
//! (`streaming.rs`); `sabotage.rs` is the trust tests' hook that makes a worker write bad
//! values.

use std::path::PathBuf;
use std::sync::Mutex;

use rogue_gym_ipc::iceoryx2::node::Node;
use rogue_gym_ipc::{IpcError, PoolId, SharedBuffer, Svc, WorkerPorts};

use crate::config::AutoresetMode;
use crate::env::MAX_INFO;
use crate::registry::{Built, EnvRegistry};
use crate::stats::StatsBuffer;
use crate::wire::answer::{BlockKind, sample_words};
use crate::wire::books::Books;
use crate::wire::slot_layout::SlotLayout;
use crate::wire::{
    BATCH_BUFFER, Command, EnvFault, WorkerConfig, env_fault_path, successor_marker,
};

mod block;
mod block_out;
mod concurrent;
mod env_state;
mod env_threads;
mod envs;
mod executor;
mod inline;
mod sabotage;
mod setup;
mod streaming;

use block::BlockHost;
use block_out::Scratch;
use env_state::EnvState;
use envs::WorkerEnvs;
use setup::{Args, parse_args, pin_to_core, read_config, wait_for_go};

#[derive(Debug, thiserror::Error)]
enum WorkerError {
    #[error(transparent)]
    Ipc(#[from] IpcError),
    #[error("{0}")]
    Msg(String),
    #[error("the supervisor (pid {0}) is gone")]
    ParentGone(i32),
}

/// Run a worker; returns the process exit code (0: closed by the supervisor or supervisor gone,
/// 2: bad arguments or config, 3: env or transport failure). Messages go to stderr, which the
/// supervisor captures for crash reports. `args` are the arguments after the program name and
/// its leading args (see the module docs). `registry` must know the pool's env kind.
pub fn worker_main(args: &[String], registry: &EnvRegistry) -> i32 {
    let a = match parse_args(args) {
        Ok(a) => a,
        Err(e) => {
            eprintln!(
                "rogue-gym worker: {e}\nusage: worker --config <file> --index <k> --generation <g> --ppid <pid> --shared-fds <batch>,<books>,<stats>"
            );
            return 2;
        }
    };
    // Die with the supervisor; then close the race where it died before prctl.
    let _ = nix::sys::prctl::set_pdeathsig(nix::sys::signal::Signal::SIGKILL);
    if nix::unistd::getppid().as_raw() != a.ppid {
        eprintln!(
            "rogue-gym worker {}: supervisor {} already gone",
            a.index, a.ppid
        );
        return 0;
    }
    let cfg: WorkerConfig = match read_config(&a.config) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("rogue-gym worker {}: {e}", a.index);
            return 2;
        }
    };
    if let Some(core) = cfg.cpu_cores.as_ref().and_then(|c| c.get(a.index))
        && let Err(e) = pin_to_core(*core)
    {
        // Not fatal: the worker runs where the kernel puts it.
        eprintln!(
            "rogue-gym worker {}: cpu_affinity not applied: {e}",
            a.index
        );
    }
    match Worker::start(&a, &cfg, registry).and_then(|mut w| w.run()) {
        Ok(()) => 0,
        Err(WorkerError::ParentGone(p)) => {
            eprintln!("rogue-gym worker {}: supervisor {p} gone, exiting", a.index);
            0
        }
        Err(e) => {
            eprintln!(
                "rogue-gym worker {} (generation {}): {e}",
                a.index, a.generation
            );
            3
        }
    }
}

/// A command taken from the port: its sequence number, the command, its payload.
struct Incoming {
    seq: u64,
    command: Command,
    payload: Vec<u64>,
}

/// A running worker: its envs, its ports, and the pool's shared memory it writes.
struct Worker<'a> {
    args: &'a Args,
    cfg: &'a WorkerConfig,
    id: PoolId,
    envs: WorkerEnvs,
    /// The block's first env (a global id).
    first_env: usize,
    /// Info values per env, command words per action, raw action bytes (0: indices).
    n_info: usize,
    action_words: usize,
    action_bytes: usize,
    /// Envs of the worker's block, and the layout of a batch slot.
    block_envs: usize,
    slot_layout: SlotLayout,
    batch: SharedBuffer,
    stats: std::sync::Arc<StatsBuffer>,
    /// The scope the env threads of a worker whose envs run on threads live in
    /// ([`EnvRegistry::set_thread_scope`]).
    thread_scope: Option<crate::registry::ThreadScope>,
    books: Books,
    /// Dropped before the node they were made from.
    ports: WorkerPorts,
    /// The worker's node (a worker whose envs run on threads makes its `CmdWaker` from it).
    node: Node<Svc>,
    /// Answers published by this process (the supervisor counts those it took:
    /// `StatsBuffer::taken`), and answers to partial commands.
    answers: u64,
    answer_no: u64,
    /// The seed schedule (re-read when a reset says so).
    seeds: crate::seeds::SeedSchedule,
    scratch: Scratch,
    /// The rows are written with streaming stores ([`streaming`]).
    streamed: bool,
    fault_path: PathBuf,
    /// Reset and step commands served so far.
    served: u64,
}

impl<'a> Worker<'a> {
    /// Build the envs of worker `a.index`, open the pool's shared memory and ports (a
    /// successor first waits for the worker it replaces to be gone), and say it is ready.
    fn start(
        a: &'a Args,
        cfg: &'a WorkerConfig,
        registry: &EnvRegistry,
    ) -> Result<Worker<'a>, WorkerError> {
        let envs = cfg.envs_of(a.index);
        if a.index >= cfg.num_workers || envs.is_empty() {
            return Err(WorkerError::Msg(format!(
                "worker index {} out of range (pool has {} workers for {} envs)",
                a.index, cfg.num_workers, cfg.num_envs
            )));
        }
        let id = PoolId::from_parts(&cfg.pool_name, &cfg.runtime_dir)?;
        // First thing: the pool's buffers, so that nothing this worker starts inherits them.
        // SAFETY: the supervisor opened these descriptors for this process (`--shared-fds`),
        // and nothing else here takes them.
        let [batch, books, stats] =
            unsafe { [0, 1, 2].map(|i| rogue_gym_ipc::buffer::take_inherited(a.shared_fds[i])) };
        let (batch, books, stats) = (batch?, books?, stats?);
        let fault_path = env_fault_path(&id, a.index, a.generation);
        let globals = envs.start as u64..envs.end as u64;
        let mut building = globals.start;
        let built = registry
            .make_block(&cfg.env, globals.clone(), |g| building = g)
            .map_err(|e| {
                // Reported like a failed step (the supervisor raises it rather than retrying).
                let fault = EnvFault::new(building, "construction", &e);
                let _ = fault.write(&fault_path);
                WorkerError::Msg(format!("cannot build env {building}: {e}"))
            })?;
        let each = |list: Vec<Box<dyn crate::Env>>| list.into_iter().zip(globals.clone());
        let (hosted, spec) = match built {
            Built::Envs(list) if cfg.env_threads > 0 => {
                let spec = list[0].spec();
                let envs = each(list).map(|(env, g)| Mutex::new(EnvState::new(env, g)));
                (WorkerEnvs::Shared(envs.collect()), spec)
            }
            Built::Envs(list) => {
                let spec = list[0].spec();
                let envs = each(list).map(|(env, g)| EnvState::new(env, g));
                (WorkerEnvs::Each(envs.collect()), spec)
            }
            Built::Block(block) => {
                let host = BlockHost::new(block, globals);
                let spec = host.spec();
                (WorkerEnvs::Block(host), spec)
            }
        };
        let n_info = spec.info_names.len().min(MAX_INFO);
        let slot_layout = SlotLayout {
            num_envs: cfg.num_envs,
            obs_bytes: spec.obs_bytes(),
            n_info,
            final_obs: cfg.autoreset == AutoresetMode::SameStep,
            extra_bytes: spec.extra_bytes,
        };
        let node = id.node(&format!("w{}g{}", a.index, a.generation))?;
        if a.successor {
            // The envs are built: the supervisor may now stop the worker this one replaces.
            rogue_gym_ipc::private::create_private_file(&successor_marker(
                &id,
                a.index,
                a.generation,
            ))?;
            wait_for_go(&id, a)?;
        }
        let ports = WorkerPorts::new(
            &node,
            a.index,
            sample_words(envs.len()),
            &cfg.channel_settings(),
        )?;
        let slots_bytes = cfg.batch_slots * slot_layout.bytes();
        // Envs write their observation to a stage first when the rows are streamed.
        let streamed = streaming::wanted(
            cfg.streaming_stores,
            cfg.batch_slots * cfg.num_envs * slot_layout.obs_bytes,
        );
        let scratch = Scratch {
            stage: if streamed {
                vec![0; slot_layout.obs_bytes]
            } else {
                Vec::new()
            },
            ..Scratch::default()
        };
        let action_words = spec.action_words();
        let mut w = Worker {
            args: a,
            cfg,
            batch: SharedBuffer::from_fd(batch, BATCH_BUFFER, slots_bytes)?,
            stats: std::sync::Arc::new(StatsBuffer::from_fd(stats, cfg.num_workers)?),
            books: Books::from_fd(books, cfg.num_envs)?,
            id,
            first_env: envs.start,
            envs: hosted,
            n_info,
            action_words,
            action_bytes: spec.action_bytes,
            block_envs: envs.len(),
            slot_layout,
            ports,
            node,
            answers: 0,
            answer_no: 0,
            seeds: cfg.seeds.clone(),
            scratch,
            streamed,
            fault_path,
            served: 0,
            thread_scope: registry.thread_scope(),
        };
        w.send(0, BlockKind::Ready)?;
        Ok(w)
    }
}
