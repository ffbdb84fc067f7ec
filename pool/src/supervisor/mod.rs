//! The supervisor ([`Pool`]): its state and life cycle (start, seeds, close).
//!
//! # One step, end to end
//!
//! A sync [`Pool::step`] (`stepping.rs`) checks the actions once ([`Actions::check`],
//! `actions.rs`) and sends each worker its block of them with the slot to write
//! (`Supervisor::send_step`, `commands.rs`: a `Command` word, `wire/command.rs`, and the
//! action words, over the worker's command port, `ipc/src/ports.rs`). The worker
//! (`worker.rs`, [`crate::worker_main`]) wakes from its wait (`ipc/src/wait.rs`), steps each
//! env of its block (`worker/envs.rs`, `worker/env_state.rs`: the env's state machine) and
//! each env writes its row of the slot in place: observation, reward, flags, episode books
//! (`worker/block_out.rs`, `wire/slot_layout.rs`). The worker then writes its envs' episode
//! books (`wire/books.rs`) and publishes one answer whose words say what else there is to
//! read (`Answer`, `wire/answer.rs`). The caller's wait ([`Pool::wait`], through the pool's
//! one wait loop in `waiting.rs`) polls the workers' answer ports (`intake.rs`:
//! `Supervisor::poll_all`, which decodes and checks every answer of every kind in one place),
//! turns each answer into a ready run of the pool's one lane (`async_api.rs`: a whole-batch
//! call is a send of every env, each worker block one run, and a receive of all of them in env
//! order, `async_envs/`, `ready_set.rs`), and returns a [`crate::Received`]: a view of the
//! slot, and whether to read final observations, restarts or extra info. The Python front
//! reads the slot's rows as numpy views (`python/src/pool/sync_api.rs`,
//! `python/rogue_gym/front/core.py`). Every file a step runs code in, with its functions, is
//! measured by `benchmarks/walk.py` (`benchmarks/results/walk/walk-step.md`).
//!
//! The async API (`async_api.rs`: `send`/`recv`, env by env) goes the same lane: the same
//! commands, a subset of a block's envs at a time, each env a run of its own with its rows in
//! a slot of its own, handed over in the order they were sent; every answer's rows are in the
//! slots. Each worker's link and its states
//! are `link.rs`, its processes `processes.rs`, its failures `failures.rs`; env calls go
//! through files (`calls.rs`); planned replacements of workers are `recycling.rs`; the
//! supervisor's state is grouped by concern in `state.rs`; how its sides wait beside other
//! pools (the machine's cores and the user's live pools) is `machine.rs`. A worker whose envs
//! run on threads (`env_concurrency`) takes the same commands and answers each env as it
//! finishes (`worker/concurrent.rs`).
//!
//! Modules: `actions`, `async_api`, `async_envs`, `calls`, `commands`, `failures`, `intake`,
//! `link`, `machine`, `processes`, `ready_set`, `recycling`, `state`,
//! `stepping`, `waiting`.

mod actions;
mod async_api;
mod async_envs;
mod calls;
mod commands;
mod failures;
mod intake;
mod link;
mod machine;
mod processes;
mod ready_set;
mod recycling;
mod state;
mod stepping;
mod waiting;

use std::collections::VecDeque;
use std::ops::Range;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use rogue_gym_ipc::{BlockListener, ChannelSettings, PoolId, SupervisorPorts, Svc};

use crate::config::{AutoresetMode, PoolConfig};
use crate::env::EnvSpec;
use crate::error::PoolError;
use crate::registry::EnvRegistry;
use crate::seeds::SeedSchedule;
use crate::stats::{StatsBuffer, SupervisorCounts, WorkerStats};
use crate::wire::books::Books;
use crate::wire::slot_layout::{Flag, SlotLayout};
use crate::wire::{
    BATCH_BUFFER, Command, Op, WorkerConfig, block_range_of, buffers_bytes, command_words, shm_need,
};

pub use actions::{Actions, validate_actions};
pub use async_api::RecvWant;
use link::WorkerLink;
pub use machine::MachineView;
use state::{AsyncState, CallInFlight, Failures, Recycling};

/// The supervisor proper: the workers (their processes, blocks, channels and layouts), the
/// shared batch buffer and the bookkeeping of the call in flight, grouped by concern
/// ([`state`]). [`Pool`] wraps it.
struct Supervisor {
    cfg: PoolConfig,
    spec: EnvSpec,
    /// The envs of each worker ([`block_range_of`]).
    blocks: Vec<Range<usize>>,
    id: PoolId,
    config_path: PathBuf,
    settings: ChannelSettings,
    workers: Vec<WorkerLink>,
    /// Workers whose answer has arrived and waits to be taken, in the order polled.
    arrived: VecDeque<usize>,
    /// Each worker's current pid, readable from other threads during a call
    /// ([`Pool::pids_handle`]).
    pids: std::sync::Arc<[std::sync::atomic::AtomicU32]>,
    node: Option<rogue_gym_ipc::iceoryx2::node::Node<Svc>>,
    batch: Option<std::sync::Arc<rogue_gym_ipc::SharedBuffer>>,
    /// The layout of every slot of the batch buffer, and each slot's rows while it is mapped.
    slot_layout: SlotLayout,
    slots: Vec<crate::wire::slot_layout::SlotRows>,
    /// The runs of envs an answer is checked over, reused answer after answer (`intake.rs`).
    runs: intake::Runs,
    /// Each env's episode index and seed, as its worker last answered ([`crate::wire::books`]).
    books: Option<Books>,
    /// The flag columns whose bytes are checked in every answer written in place
    /// (`Supervisor::check_flags`).
    flags: Vec<crate::wire::slot_layout::Flag>,
    /// Bytes the pool needs in /dev/shm ([`Pool::shm_bytes`]), and its own buffers'
    /// ([`Pool::buffer_bytes`]).
    shm_need: u64,
    buffers_need: u64,
    next_slot: usize,
    /// The workers' envs run on threads ([`PoolConfig::env_threads`], envs of one `Env` each):
    /// async steps in place go as partial commands, answered env by env.
    concurrent: bool,
    /// The machine: its usable cores and the user's other pools, from which the pool decides
    /// how its workers and its caller wait (`machine.rs`).
    machine: machine::Machine,
    closed: bool,
    /// Workers must re-read the seed schedule at their next reset.
    reload_seeds: Vec<bool>,
    worker_config: Option<WorkerConfig>,
    /// The first start is over (every worker was ready once): from then on a worker that
    /// exits while starting is a crash like any other, not a broken worker command.
    started: bool,
    /// The call in progress.
    call: CallInFlight,
    /// The EnvPool-style async API's state.
    async_api: AsyncState,
    /// Worker failures over the pool's life.
    failures: Failures,
    /// Workers replaced by plan ([`recycling`]).
    recycling: Recycling,
    /// The workers' counters in shared memory ([`Pool::stats`]), and what this side counts.
    stats: Option<StatsBuffer>,
    counts: Vec<SupervisorCounts>,
}

/// A pool of envs stepped by worker processes, with observations in shared memory.
///
/// Thread-safety: `Pool` is `Send` (not `Sync`): use it from one thread at a time (a Python
/// `#[pyclass]` can hold it behind a mutex). Workers are spawned from the thread that calls
/// [`Pool::new`] and get `SIGKILL` when *that thread* exits (PDEATHSIG), besides watching the
/// supervisor's pid: create the pool on a long-lived thread.
pub struct Pool {
    listener: Option<BlockListener>,
    sup: Supervisor,
    interrupt: Option<InterruptCheck>,
}

/// A callback run between the slices of a long wait (see [`Pool::set_interrupt_check`]);
/// returning `true` aborts the call with [`PoolError::Interrupted`].
pub type InterruptCheck = Box<dyn FnMut() -> bool + Send>;

impl std::fmt::Debug for Pool {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pool")
            .field("name", &self.sup.id.name())
            .field("num_envs", &self.sup.cfg.num_envs)
            .field("num_workers", &self.sup.cfg.num_workers)
            .finish()
    }
}

impl Pool {
    /// Start a pool: sweep stale pools, build one env locally to learn the spec, spawn the
    /// workers and wait until all are ready. Call [`Pool::reset`] or [`Pool::async_reset`]
    /// next.
    pub fn new(cfg: PoolConfig, registry: &EnvRegistry) -> Result<Pool, PoolError> {
        Pool::with_interrupt_check(cfg, registry, None)
    }

    /// [`Pool::new`] with [`Pool::set_interrupt_check`]'s check already installed, so that it
    /// runs while the workers start too: a start-up of envs slow to build (its bound is
    /// `start_timeout`) can be interrupted, with [`PoolError::Interrupted`], and everything it
    /// started is cleaned up.
    pub fn with_interrupt_check(
        cfg: PoolConfig,
        registry: &EnvRegistry,
        interrupt: Option<InterruptCheck>,
    ) -> Result<Pool, PoolError> {
        cfg.validate()?;
        let unit = cfg.block_unit;
        let blocks: Vec<Range<usize>> = (0..cfg.num_workers)
            .map(|k| block_range_of(cfg.num_envs, cfg.num_workers, k, unit))
            .collect();
        let spec = match &cfg.spec {
            Some(s) => s.clone(),
            None => registry.make(&cfg.env, 0)?.spec(),
        };
        spec.validate()?;
        let aw = spec.action_words();
        let whole_blocks = registry.builds_blocks(&cfg.env);
        let slot_layout = SlotLayout {
            num_envs: cfg.num_envs,
            obs_bytes: spec.obs_bytes(),
            n_info: spec.info_names.len(),
            final_obs: cfg.autoreset == AutoresetMode::SameStep,
            extra_bytes: spec.extra_bytes,
        };
        // Before anything is created: a pool that does not fit /dev/shm fails now, with the
        // fixes, not later with a SIGBUS in a worker.
        let shm_need = shm_need(&blocks, spec.action_words());
        let buffers_need = buffers_bytes(cfg.batch_slots, &slot_layout, cfg.num_workers);
        let mut flags = vec![Flag::Terminated, Flag::Truncated];
        flags.extend(spec.flag_info_rows().into_iter().map(Flag::Info));
        if slot_layout.final_obs {
            flags.push(Flag::HasFinalObs);
        }
        rogue_gym_ipc::check_room(shm_need)?;
        let runtime_dir = rogue_gym_ipc::resolve_runtime_dir(cfg.runtime_dir.as_deref())?;
        rogue_gym_ipc::sweep_stale_pools(&runtime_dir);
        let id = PoolId::new_unique(&runtime_dir)?;
        // In the ledger from here on (left when `machine` drops: on any error below, at close).
        let (machine, pinned) =
            machine::Machine::join(&runtime_dir, id.name(), cfg.num_workers, cfg.cpu_affinity)?;
        id.create_dirs()?;
        let settings = ChannelSettings {
            num_workers: cfg.num_workers,
        };
        let wcfg = WorkerConfig::new(&cfg, id.name(), runtime_dir, pinned);
        let config_path = id.aux_dir().join("worker.json");
        let num_workers = cfg.num_workers;
        let concurrent = cfg.env_threads > 0 && !whole_blocks;
        let envs = async_envs::AsyncEnvs::new(&blocks, aw, cfg.batch_slots);
        let mut pool = Pool {
            listener: None,
            interrupt,
            sup: Supervisor {
                cfg,
                spec,
                blocks,
                id,
                config_path,
                settings,
                workers: Vec::new(),
                arrived: VecDeque::new(),
                pids: (0..num_workers).map(|_| Default::default()).collect(),
                node: None,
                concurrent,
                machine,
                batch: None,
                slot_layout,
                slots: Vec::new(),
                runs: Vec::new(),
                books: None,
                flags,
                shm_need,
                buffers_need,
                next_slot: 0,
                closed: false,
                reload_seeds: vec![false; num_workers],
                worker_config: None,
                started: false,
                call: CallInFlight::new(),
                async_api: AsyncState::new(envs, whole_blocks),
                failures: Failures::new(),
                recycling: Recycling::default(),
                stats: None,
                counts: Vec::new(),
            },
        };
        // From here on, Drop cleans up whatever was created.
        pool.start(&wcfg)?;
        pool.sup.worker_config = Some(wcfg);
        Ok(pool)
    }

    fn start(&mut self, wcfg: &WorkerConfig) -> Result<(), PoolError> {
        let c = &mut self.sup;
        let json = serde_json::to_string(wcfg)
            .map_err(|e| PoolError::Config(format!("cannot serialize worker config: {e}")))?;
        rogue_gym_ipc::private::write_private_file(&c.config_path, json.as_bytes())?;
        c.stats = Some(StatsBuffer::create(c.cfg.num_workers)?);
        c.books = Some(Books::create(c.cfg.num_envs)?);
        c.counts = vec![SupervisorCounts::default(); c.cfg.num_workers];
        c.batch = Some(std::sync::Arc::new(rogue_gym_ipc::SharedBuffer::create(
            BATCH_BUFFER,
            c.cfg.batch_slots * c.slot_layout.bytes(),
        )?));
        c.make_slot_rows();
        // Right after the pool's first /dev/shm file, before any node: iceoryx2's node counter,
        // private (see rogue_gym_ipc::create_node_counter).
        rogue_gym_ipc::create_node_counter(&c.id)?;
        let node = c.id.node("sup")?;
        self.listener = Some(BlockListener::new(&node, &c.settings)?);
        for k in 0..c.cfg.num_workers {
            let words = command_words(c.blocks[k].len(), c.spec.action_words());
            let ports = SupervisorPorts::new(&node, k, words)?;
            c.workers.push(WorkerLink::new(ports));
        }
        c.node = Some(node);
        self.begin_call()?;
        let c = &mut self.sup;
        for k in 0..c.cfg.num_workers {
            c.spawn(k, false)?;
        }
        self.wait_until(|c| !c.workers.iter().any(|s| s.state.coming_back()))?;
        self.sup.started = true;
        rogue_gym_ipc::verify_pool_files(&self.sup.id)?;
        Ok(())
    }

    /// Replace the seed schedule and restart every env's episode count: the next reset
    /// ([`Pool::reset`], [`Pool::send_reset`] or [`Pool::async_reset`], which you must call
    /// next) starts episode 0 of every env under `seeds`, so the run continues exactly as a
    /// fresh pool created with `seeds` would (gymnasium's `reset(seed=...)`). Outstanding
    /// async results are discarded.
    pub fn set_seeds(&mut self, seeds: SeedSchedule) -> Result<(), PoolError> {
        self.begin_call()?;
        seeds
            .validate(self.sup.cfg.num_envs as u64)
            .map_err(PoolError::Config)?;
        self.drain()?;
        let c = &mut self.sup;
        let mut wcfg = c
            .worker_config
            .clone()
            .ok_or_else(|| PoolError::State("the pool is not started".into()))?;
        wcfg.seeds = seeds.clone();
        let json = serde_json::to_string(&wcfg)
            .map_err(|e| PoolError::Config(format!("cannot serialize worker config: {e}")))?;
        // Written then renamed, so a worker (re)reading it never sees a partial file.
        rogue_gym_ipc::private::write_private_file(&c.config_path, json.as_bytes())?;
        c.cfg.seeds = seeds;
        c.worker_config = Some(wcfg);
        c.workers.iter_mut().for_each(|s| s.first_episodes = true);
        c.reload_seeds.iter_mut().for_each(|r| *r = true);
        c.failures.must_reset = true;
        Ok(())
    }

    /// The env spec (observation shape and dtype, actions, info names).
    pub fn spec(&self) -> &EnvSpec {
        &self.sup.spec
    }
    /// Number of envs.
    pub fn num_envs(&self) -> usize {
        self.sup.cfg.num_envs
    }
    /// Number of workers.
    pub fn num_workers(&self) -> usize {
        self.sup.cfg.num_workers
    }
    /// Bytes the pool maps in `/dev/shm`, checked against its free space before the pool was
    /// created: its workers' channels, each file in whole pages (every answer's rows are in
    /// the pool's own buffers, [`Pool::buffer_bytes`]).
    pub fn shm_bytes(&self) -> u64 {
        self.sup.shm_need
    }
    /// Bytes of the pool's own buffers (the batch slots, the episode books, the counters):
    /// memory of the process, not of `/dev/shm`, its pages reserved when the pool was made.
    pub fn buffer_bytes(&self) -> u64 {
        self.sup.buffers_need
    }
    /// The envs whose worker was replaced by plan (`recycle_after_steps`,
    /// `recycle_above_rss`) during the last call (async: the rows of the last `recv` whose
    /// worker was replaced since they were sent): they report `restarted`, and their episodes
    /// were cut there, between two commands.
    pub fn recycled_envs(&self) -> &[usize] {
        &self.sup.recycling.replaced_envs
    }
    /// The envs worker `k` hosts (contiguous; blocks differ by at most one env, the larger
    /// first).
    pub fn worker_envs(&self, k: usize) -> Range<usize> {
        self.sup.blocks.get(k).cloned().unwrap_or(0..0)
    }
    /// Envs per async [`Pool::recv`].
    pub fn batch_size(&self) -> usize {
        self.sup.cfg.batch_size.unwrap_or(self.sup.cfg.num_envs)
    }
    /// Bytes of one observation.
    pub fn obs_bytes(&self) -> usize {
        self.sup.spec.obs_bytes()
    }
    /// The pool's files (name, prefix, directories).
    pub fn id(&self) -> &PoolId {
        &self.sup.id
    }
    /// Current worker pids (index = worker).
    pub fn worker_pids(&self) -> Vec<u32> {
        self.sup.workers.iter().map(|s| s.pid).collect()
    }
    /// The workers' current pids (index = worker) as a shared handle that other threads may
    /// read at any time, even while a call runs (a monitor, a chaos test); a worker is 0 before
    /// its first start and after [`Pool::close`].
    pub fn pids_handle(&self) -> std::sync::Arc<[std::sync::atomic::AtomicU32]> {
        self.sup.pids.clone()
    }
    /// The machine as this pool sees it: its usable cores, the demand it counts, how its
    /// workers and caller wait, and the user's other live pools (`supervisor/machine.rs`).
    pub fn machine(&mut self) -> MachineView {
        self.sup.machine.view()
    }
    /// Worker restarts so far.
    pub fn restarts(&self) -> u32 {
        self.sup.failures.restarts
    }
    /// Worker deaths and hangs so far, under either failure policy.
    pub fn worker_deaths(&self) -> u32 {
        self.sup.failures.deaths
    }
    /// Each worker's statistics since the pool started (see [`crate::stats`]): read from the
    /// workers' counters in shared memory, no message; empty once closed.
    pub fn stats(&self) -> Vec<WorkerStats> {
        let c = &self.sup;
        match &c.stats {
            Some(buf) => (0..c.cfg.num_workers)
                .map(|k| buf.worker(k, &c.counts[k]))
                .collect(),
            None => Vec::new(),
        }
    }
    /// The longest any call may take before it returns or raises
    /// [`PoolError::NotBackInTime`]: `step_timeout + start_timeout` (a command's own time, then
    /// the time to bring a lost worker back: its backoff, start-up and the reset of its envs).
    /// `None` when there is no `step_timeout`: a call then waits as long as live workers take,
    /// but at most `start_timeout` from the first worker failure it sees.
    pub fn call_bound(&self) -> Option<Duration> {
        self.sup
            .cfg
            .step_timeout
            .map(|t| t + self.sup.cfg.start_timeout)
    }
    /// Install (or remove) a check run between the slices of any wait that has lasted at least
    /// 5 ms (every `PoolConfig::wait.block_slice`, 10 ms by default): if it returns `true`, the
    /// call fails with [`PoolError::Interrupted`] and the pool needs a reset (outstanding
    /// requests are abandoned and drained by the reset). Bindings use it to deliver Ctrl-C
    /// during a long wait (e.g. Python's `check_signals` with the GIL re-acquired briefly).
    /// Returns the check it replaces, so that a caller on a thread that must not run it (an
    /// XLA handler) can put it back afterwards.
    pub fn set_interrupt_check(&mut self, check: Option<InterruptCheck>) -> Option<InterruptCheck> {
        std::mem::replace(&mut self.interrupt, check)
    }

    /// Run `f` (a call of this pool) so that a panic in it (a bug) becomes
    /// [`PoolError::Internal`] rather than unwinding into the caller: the pool then needs a
    /// reset, and stays usable (a binding that keeps the pool behind a mutex runs its calls
    /// through this, so that the mutex is never poisoned).
    pub fn guarded<R>(
        &mut self,
        f: impl FnOnce(&mut Pool) -> Result<R, PoolError>,
    ) -> Result<R, PoolError> {
        // Unwind safety: after a panic the pool is only reset (which rebuilds the state of
        // every call) or closed.
        match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(&mut *self))) {
            Ok(r) => r,
            Err(panic) => {
                self.sup.failures.must_reset = true;
                let what = panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "a panic".into());
                Err(PoolError::Internal(what))
            }
        }
    }

    /// Start a public call: the pool must be open; the call's bound counts from now.
    fn begin_call(&mut self) -> Result<(), PoolError> {
        if self.sup.closed {
            return Err(PoolError::Closed);
        }
        self.sup.call.started = Instant::now();
        self.sup.call.failed_at = None;
        self.sup.recycling.replaced_envs.clear();
        Ok(())
    }

    /// Every worker idle, for a sync call: the usual case is read off the link states, and
    /// only a worker still coming back (raise policy, or a call that outlived its bound) is
    /// waited for; an outstanding async request is an error. `slots`: the call writes a
    /// slot, so async results not yet received are outstanding too (their rows are in the
    /// slots).
    fn all_idle(&mut self, slots: bool) -> Result<(), PoolError> {
        let pending = "async requests are outstanding: recv() them before a sync reset/step";
        let received = |c: &Supervisor| !slots || c.async_api.envs.outstanding() == 0;
        if received(&self.sup) && self.sup.workers.iter().all(|s| s.state.is_idle()) {
            return Ok(());
        }
        self.wait_until(|c| !c.workers.iter().any(|s| s.state.coming_back()))?;
        if !received(&self.sup) || self.sup.workers.iter().any(|s| !s.state.is_idle()) {
            return Err(PoolError::State(pending.into()));
        }
        Ok(())
    }

    /// Wait for every outstanding request (and starting worker) and discard the results,
    /// env errors of those requests included.
    fn drain(&mut self) -> Result<(), PoolError> {
        self.sup.call.sent = None;
        self.sup.call.faults.clear();
        self.sup.call.discard_faults = true;
        let drained = self.wait_until(|c| {
            !c.workers
                .iter()
                .any(|s| s.state.coming_back() || s.state.is_pending())
        });
        self.sup.call.discard_faults = false;
        drained?;
        for s in &mut self.sup.workers {
            s.forget_answer();
            s.restarted = false;
        }
        self.sup.arrived.clear();
        self.sup.async_api.envs.clear();
        self.sup.async_api.on = false;
        Ok(())
    }

    /// Stop the workers and remove every file of the pool (`/dev/shm` and directories).
    /// Idempotent; also run by `Drop`. Blocks still held by the caller stay readable.
    pub fn close(&mut self) -> Result<(), PoolError> {
        if self.sup.closed {
            return Ok(());
        }
        self.sup.closed = true;
        for k in 0..self.sup.workers.len() {
            self.sup.drop_successor(k, None);
        }
        let c = &mut self.sup;
        for s in &c.workers {
            if s.child.is_some() {
                let close = Command::new(Op::Close, 0).encode();
                let _ = s.ports.send_cmd(u64::MAX, close, 0, |_| {});
            }
        }
        let deadline = Instant::now() + Duration::from_millis(300);
        for s in &mut c.workers {
            if let Some(mut ch) = s.child.take() {
                loop {
                    match ch.try_wait() {
                        Ok(Some(_)) => break,
                        Ok(None) if Instant::now() < deadline => {
                            std::thread::sleep(Duration::from_millis(1))
                        }
                        _ => {
                            let _ = ch.kill();
                            let _ = ch.wait();
                            break;
                        }
                    }
                }
            }
        }
        c.arrived.clear();
        c.async_api.envs.clear();
        c.workers.clear();
        c.pids
            .iter()
            .for_each(|p| p.store(0, std::sync::atomic::Ordering::Relaxed));
        c.machine.leave();
        self.listener = None;
        c.node = None;
        // Views of the batch buffer may outlive the pool; its descriptor does not.
        c.slots.clear();
        if let Some(b) = c.batch.take() {
            b.close_fd();
        }
        c.books = None;
        c.stats = None;
        rogue_gym_ipc::remove_pool_files(&c.id)?;
        Ok(())
    }
}

impl Supervisor {
    /// Env `i` (of worker `k`)'s episode index and seed as the worker last answered, or
    /// `None` before its first answer under the current seed schedule.
    fn book(&self, k: usize, i: usize) -> Option<(u64, u64)> {
        let s = &self.workers[k];
        match (&self.books, s.delivered) {
            (Some(b), Some(seq)) if !s.first_episodes => Some(b.read(seq, i)),
            _ => None,
        }
    }
}

impl Drop for Pool {
    fn drop(&mut self) {
        let _ = self.close();
    }
}
