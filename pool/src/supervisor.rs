//! The supervisor: spawns the workers, sends them actions, gathers their blocks, and restarts
//! failed workers.

use std::collections::VecDeque;
use std::fs;
use std::io::{Read, Seek, SeekFrom};
use std::ops::Range;
use std::os::unix::process::ExitStatusExt;
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use rogue_gym_ipc::{
    BlockListener, BlockSample, ChannelSettings, IpcError, PoolId, SupervisorPorts, Svc, WaitCall,
    WaitOutcome, WaitPolicy, hybrid_wait,
};
use serde_json::Value;

use crate::env::{EnvError, EnvRegistry, EnvSpec};
use crate::layout::{BlockLayout, EnvRecord, FLAG_RESTARTED, FLAG_TRUNCATED};
use crate::seeds::SeedSchedule;
use crate::worker::{
    AutoresetMode, BATCH_BUFFER, BATCH_SLOTS, BLOCK_DATA, BLOCK_READY, CMD_CLOSE, CMD_RESET,
    CMD_STEP, KEEP_EPISODE, RELOAD_SEEDS, TARGET_SHIFT, WorkerConfig, slot_bytes,
};

/// What to do when a worker dies or hangs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FailurePolicy {
    /// Respawn the worker and re-seed its envs from the schedule; the affected envs report
    /// `truncated` plus the restart flag.
    #[default]
    Restart,
    /// Respawn the worker (so the pool is usable after `reset`) but return
    /// [`PoolError::WorkerFailed`].
    Raise,
}

/// How to start a worker process: `program args... --config F --index K --generation G --ppid P`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WorkerCommand {
    /// The executable (e.g. the `rogue-gym` binary, or the Python interpreter).
    pub program: PathBuf,
    /// Leading arguments (e.g. `["worker"]`, or `["-m", "rogue_gym.worker"]`).
    pub args: Vec<String>,
}

impl WorkerCommand {
    /// The current executable with the given leading args (e.g. `["worker"]` for the CLI).
    /// Inside a Python extension the current executable is the interpreter: build the command
    /// explicitly there.
    pub fn current_exe(args: &[&str]) -> Result<Self, PoolError> {
        let program = std::env::current_exe()
            .map_err(|e| PoolError::Config(format!("cannot locate the current executable: {e}")))?;
        Ok(WorkerCommand {
            program,
            args: args.iter().map(|s| s.to_string()).collect(),
        })
    }
}

/// Configuration of a pool.
#[derive(Debug, Clone)]
pub struct PoolConfig {
    /// JSON spec of the env (its `"kind"` selects the constructor in the [`EnvRegistry`]).
    pub env: Value,
    /// Total envs; must be a multiple of `num_workers`.
    pub num_envs: usize,
    /// Worker processes; each steps `num_envs / num_workers` envs.
    pub num_workers: usize,
    /// Envs returned by one async [`Pool::recv`]; a multiple of the envs per worker. `None`:
    /// all envs.
    pub batch_size: Option<usize>,
    /// Episode seed schedule.
    pub seeds: SeedSchedule,
    /// Autoreset mode.
    pub autoreset: AutoresetMode,
    /// Policy on a worker failure.
    pub on_worker_failure: FailurePolicy,
    /// A worker that has not answered a command after this long is killed and treated as
    /// failed (`None`: wait forever, but still detect deaths).
    pub step_timeout: Option<Duration>,
    /// Time a worker gets to start (open its ports and say it is ready).
    pub start_timeout: Duration,
    /// Worker restarts allowed over the pool's life; one more fails with
    /// [`PoolError::RestartBudgetExceeded`].
    pub max_restarts: u32,
    /// Blocks of one worker the caller may hold at once, plus one (see [`Block`]).
    pub max_borrowed: usize,
    /// How to start a worker.
    pub worker: WorkerCommand,
    /// Supervisor's waiting policy.
    pub wait: WaitPolicy,
    /// Workers' waiting policy.
    pub worker_wait: WaitPolicy,
    /// Directory holding the pools' short roots (default `/tmp/rgp`).
    pub base_dir: PathBuf,
}

impl PoolConfig {
    /// A config with defaults: NEXT_STEP autoreset, restart policy, no step timeout, 30 s start
    /// timeout, 100 restarts, 4 borrowed samples, base seed 0.
    pub fn new(env: Value, num_envs: usize, num_workers: usize, worker: WorkerCommand) -> Self {
        PoolConfig {
            env,
            num_envs,
            num_workers,
            batch_size: None,
            seeds: SeedSchedule::default(),
            autoreset: AutoresetMode::NextStep,
            on_worker_failure: FailurePolicy::Restart,
            step_timeout: None,
            start_timeout: Duration::from_secs(30),
            max_restarts: 100,
            max_borrowed: 4,
            worker,
            wait: WaitPolicy {
                poll_budget: Duration::from_micros(50),
                block_slice: Duration::from_millis(10),
                yield_cpu: true,
            },
            worker_wait: WaitPolicy {
                poll_budget: Duration::from_micros(50),
                block_slice: Duration::from_millis(100),
                yield_cpu: true,
            },
            base_dir: PathBuf::from(rogue_gym_ipc::DEFAULT_BASE_DIR),
        }
    }
}

/// Why a worker failed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FailureCause {
    /// The process exited or was killed.
    Died,
    /// It did not answer within the step timeout and was killed.
    Hung(Duration),
}

/// Report on a failed worker.
#[derive(Debug, Clone)]
pub struct WorkerFailure {
    /// Worker index.
    pub worker: usize,
    /// The envs it hosted.
    pub env_ids: Range<usize>,
    /// Its process id.
    pub pid: u32,
    /// Died or hung.
    pub cause: FailureCause,
    /// Exit code, if it exited.
    pub exit_code: Option<i32>,
    /// Signal number, if it was killed by one.
    pub signal: Option<i32>,
    /// Seeds of the episodes that were cut.
    pub seeds: Vec<u64>,
    /// The end of its stderr.
    pub stderr_tail: String,
}

impl std::fmt::Display for WorkerFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "worker {} (pid {}, envs {}..{}) ",
            self.worker, self.pid, self.env_ids.start, self.env_ids.end
        )?;
        match &self.cause {
            FailureCause::Hung(t) => {
                write!(f, "hung: no answer within step_timeout {t:?}, killed")?
            }
            FailureCause::Died => match (self.signal, self.exit_code) {
                (Some(s), _) => write!(f, "was killed by signal {s} ({})", signal_name(s))?,
                (None, Some(c)) => write!(f, "exited with code {c}")?,
                _ => write!(f, "died")?,
            },
        }
        if !self.seeds.is_empty() {
            write!(f, "; episode seeds {:?}", self.seeds)?;
        }
        if self.stderr_tail.trim().is_empty() {
            write!(f, "; its stderr was empty")
        } else {
            write!(f, "; end of its stderr:\n{}", self.stderr_tail.trim_end())
        }
    }
}

fn signal_name(s: i32) -> &'static str {
    nix::sys::signal::Signal::try_from(s)
        .map(|s| s.as_str())
        .unwrap_or("unknown")
}

/// Errors of the pool. Messages say what was wrong and how to fix it.
#[derive(Debug, thiserror::Error)]
pub enum PoolError {
    /// Invalid configuration.
    #[error("invalid pool configuration: {0}")]
    Config(String),
    /// The env could not be built.
    #[error("env: {0}")]
    Env(#[from] EnvError),
    /// Transport failure.
    #[error("shared-memory transport: {0}")]
    Ipc(#[from] IpcError),
    /// Wrong number of actions.
    #[error("got {got} actions for {expected} envs: pass exactly one action per env")]
    BadActionsLength {
        /// Expected count.
        expected: usize,
        /// Given count.
        got: usize,
    },
    /// An action out of range.
    #[error("env {env}: action {value} is out of range; valid actions are 0..{num_actions}")]
    BadAction {
        /// Env id.
        env: usize,
        /// The bad value.
        value: i64,
        /// Number of actions.
        num_actions: usize,
    },
    /// A caller buffer has the wrong size.
    #[error("{what} has {got} bytes, expected {expected}")]
    BadBuffer {
        /// Which buffer.
        what: &'static str,
        /// Expected size.
        expected: usize,
        /// Given size.
        got: usize,
    },
    /// A call out of order (e.g. step before reset, send to envs still running).
    #[error("{0}")]
    State(String),
    /// A worker could not be started.
    #[error("worker {worker} failed to start: {reason}{}", if stderr_tail.trim().is_empty() { String::new() } else { format!("; end of its stderr:\n{}", stderr_tail.trim_end()) })]
    StartFailed {
        /// Worker index.
        worker: usize,
        /// What happened.
        reason: String,
        /// The end of its stderr.
        stderr_tail: String,
    },
    /// A worker died or hung (policy `raise`). The pool respawned it: call `reset` to go on.
    #[error("{0}; call reset() to continue")]
    WorkerFailed(Box<WorkerFailure>),
    /// Too many restarts.
    #[error("restart budget exhausted ({max_restarts} restarts); last failure: {last}")]
    RestartBudgetExceeded {
        /// The budget.
        max_restarts: u32,
        /// The failure that exceeded it.
        last: Box<WorkerFailure>,
    },
    /// The interrupt check ([`Pool::set_interrupt_check`]) asked to abort a wait. Outstanding
    /// requests are abandoned: call a reset to go on.
    #[error("interrupted while waiting for the workers; call reset() to continue")]
    Interrupted,
    /// The pool is closed.
    #[error("the pool is closed")]
    Closed,
    /// File-system error on the pool's own files.
    #[error("{0}")]
    Io(String),
}

enum SlotState {
    /// Process started, waiting for its READY block.
    Starting { since: Instant, then_reset: bool },
    /// Nothing outstanding.
    Idle,
    /// A command is outstanding.
    Pending { since: Instant },
    /// Its answer has arrived and waits to be handed out.
    Ready(BlockSample),
}

struct WorkerSlot {
    ports: SupervisorPorts,
    child: Option<Child>,
    pid: u32,
    generation: u64,
    seq: u64,
    state: SlotState,
    restarted: bool,
    stderr_path: PathBuf,
    /// Observation target of the last command (see `TARGET_SHIFT`).
    target: u32,
}

/// Per-env arrays of one batch (sync step/reset, or filled from an async [`Batch`]). Row `r`
/// describes env `env_ids[r]`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BatchOutput {
    /// Env ids of the rows.
    pub env_ids: Vec<usize>,
    /// Rewards.
    pub reward: Vec<f32>,
    /// Episode ended by the rules.
    pub terminated: Vec<bool>,
    /// Episode cut (step limit or worker restart).
    pub truncated: Vec<bool>,
    /// The env's worker was restarted (its episode was cut; the obs is a new episode's first).
    pub restarted: Vec<bool>,
    /// Episode return so far (of the ended episode on a final step).
    pub episode_return: Vec<f64>,
    /// Episode length so far.
    pub episode_length: Vec<u32>,
    /// Episode index (the `e` of the seed schedule).
    pub episode: Vec<u64>,
    /// Episode seed.
    pub seed: Vec<u64>,
    /// Env-defined info values, row-major `rows x info_names.len()`.
    pub info: Vec<f64>,
    /// (SAME_STEP) whether `final_obs` row `r` is valid.
    pub has_final_obs: Vec<bool>,
    /// (SAME_STEP) final observations, `rows x obs_bytes`; empty in NEXT_STEP mode.
    pub final_obs: Vec<u8>,
}

impl BatchOutput {
    fn clear(&mut self) {
        self.env_ids.clear();
        self.reward.clear();
        self.terminated.clear();
        self.truncated.clear();
        self.restarted.clear();
        self.episode_return.clear();
        self.episode_length.clear();
        self.episode.clear();
        self.seed.clear();
        self.info.clear();
        self.has_final_obs.clear();
        self.final_obs.clear();
    }

    fn push(&mut self, env: usize, r: &EnvRecord, n_info: usize, fin: Option<&[u8]>) {
        self.env_ids.push(env);
        self.reward.push(r.reward);
        self.terminated.push(r.terminated());
        self.truncated.push(r.truncated());
        self.restarted.push(r.restarted());
        self.episode_return.push(r.episode_return);
        self.episode_length.push(r.episode_length);
        self.episode.push(r.episode);
        self.seed.push(r.seed);
        self.info.extend_from_slice(&r.info[..n_info]);
        if let Some(f) = fin {
            self.has_final_obs.push(r.has_final_obs());
            if r.has_final_obs() {
                self.final_obs.extend_from_slice(f);
            } else {
                self.final_obs.resize(self.final_obs.len() + f.len(), 0);
            }
        } else {
            self.has_final_obs.push(false);
        }
    }
}

/// One worker's block as received: an owned handle on the shared-memory sample (`Send`).
///
/// Lifetime: the observation bytes stay valid and unchanged for as long as the `Block` lives,
/// even after the pool is closed. Each held block pins one of its worker's
/// `max_borrowed` sample slots: holding `max_borrowed` blocks of one worker makes the next
/// receive from that worker fail, so keep at most `max_borrowed - 1` per worker.
pub struct Block {
    worker: usize,
    env_start: usize,
    layout: BlockLayout,
    restarted: bool,
    sample: BlockSample,
}

impl std::fmt::Debug for Block {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Block")
            .field("worker", &self.worker)
            .field("env_ids", &self.env_ids())
            .finish()
    }
}

impl Block {
    /// The worker that produced it.
    pub fn worker(&self) -> usize {
        self.worker
    }
    /// Env ids of its rows.
    pub fn env_ids(&self) -> Range<usize> {
        self.env_start..self.env_start + self.layout.envs
    }
    /// Its observations: `envs x obs_bytes` C-contiguous bytes in shared memory (read-only),
    /// 8-byte aligned.
    pub fn obs(&self) -> &[u8] {
        self.layout.obs(self.sample.payload())
    }
    /// (SAME_STEP) its final observations, same layout as [`Block::obs`].
    pub fn final_obs(&self) -> Option<&[u8]> {
        self.layout.final_obs(self.sample.payload())
    }
    /// Record of row `j` (with the restart flags applied).
    pub fn record(&self, j: usize) -> EnvRecord {
        let mut r = self.layout.record(self.sample.payload(), j);
        if self.restarted {
            r.flags = FLAG_TRUNCATED | FLAG_RESTARTED;
            r.reward = 0.0;
        }
        r
    }
    /// Whether this block answers a worker restart.
    pub fn restarted(&self) -> bool {
        self.restarted
    }
    /// The underlying iceoryx2 sample (records, then observations; see `layout`).
    pub fn sample(&self) -> &BlockSample {
        &self.sample
    }
    /// Give up the block, keeping only the iceoryx2 sample (the memory stays valid while it
    /// lives). Note: restart flags are applied by [`Block::record`], not stored in the sample.
    pub fn into_sample(self) -> BlockSample {
        self.sample
    }
}

/// The blocks returned by one async [`Pool::recv`], in arrival order.
#[derive(Debug)]
pub struct Batch {
    /// The blocks.
    pub blocks: Vec<Block>,
}

impl Batch {
    /// Env ids of all rows, in block order.
    pub fn env_ids(&self) -> Vec<usize> {
        self.blocks.iter().flat_map(|b| b.env_ids()).collect()
    }
    /// Copy the observations into `out` (rows in [`Batch::env_ids`] order).
    pub fn copy_obs_into(&self, out: &mut [u8]) -> Result<(), PoolError> {
        let total: usize = self.blocks.iter().map(|b| b.obs().len()).sum();
        if out.len() != total {
            return Err(PoolError::BadBuffer {
                what: "observation buffer",
                expected: total,
                got: out.len(),
            });
        }
        let mut off = 0;
        for b in &self.blocks {
            let o = b.obs();
            out[off..off + o.len()].copy_from_slice(o);
            off += o.len();
        }
        Ok(())
    }
    /// Fill the per-env arrays (rows in [`Batch::env_ids`] order).
    pub fn fill(&self, n_info: usize, out: &mut BatchOutput) {
        out.clear();
        self.fill_append(n_info, out);
    }
}

struct Core {
    cfg: PoolConfig,
    spec: EnvSpec,
    layout: BlockLayout,
    epw: usize,
    id: PoolId,
    config_path: PathBuf,
    settings: ChannelSettings,
    slots: Vec<WorkerSlot>,
    node: Option<rogue_gym_ipc::iceoryx2::node::Node<Svc>>,
    batch: Option<std::sync::Arc<rogue_gym_ipc::SharedBuffer>>,
    slot_bytes: usize,
    next_slot: usize,
    ready_order: VecDeque<usize>,
    cur_episode: Vec<Option<u64>>,
    cur_seed: Vec<u64>,
    restarts: u32,
    must_reset: bool,
    closed: bool,
    /// Workers must re-read the seed schedule at their next reset.
    reload_seeds: Vec<bool>,
    worker_config: Option<WorkerConfig>,
}

/// A pool of envs stepped by worker processes, with observations in shared memory.
///
/// Thread-safety: `Pool` is `Send` (not `Sync`): use it from one thread at a time (a Python
/// `#[pyclass]` can hold it behind a mutex). Workers are spawned from the thread that calls
/// [`Pool::new`] and get `SIGKILL` when *that thread* exits (PDEATHSIG), besides watching the
/// supervisor's pid: create the pool on a long-lived thread.
pub struct Pool {
    listener: Option<BlockListener>,
    core: Core,
    interrupt: Option<InterruptCheck>,
}

/// A callback run between the slices of a long wait (see [`Pool::set_interrupt_check`]);
/// returning `true` aborts the call with [`PoolError::Interrupted`].
pub type InterruptCheck = Box<dyn FnMut() -> bool + Send>;

/// How long a wait must have lasted before the interrupt check runs (it runs between blocking
/// wait slices, every `PoolConfig::wait.block_slice`, so the hot path never calls it).
const INTERRUPT_AFTER: Duration = Duration::from_millis(5);

impl std::fmt::Debug for Pool {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pool")
            .field("name", &self.core.id.name())
            .field("num_envs", &self.core.cfg.num_envs)
            .field("num_workers", &self.core.cfg.num_workers)
            .finish()
    }
}

fn stderr_tail(path: &PathBuf) -> String {
    const N: u64 = 2048;
    let Ok(mut f) = fs::File::open(path) else {
        return String::new();
    };
    let len = f.metadata().map(|m| m.len()).unwrap_or(0);
    let _ = f.seek(SeekFrom::Start(len.saturating_sub(N)));
    let mut buf = Vec::new();
    let _ = f.read_to_end(&mut buf);
    String::from_utf8_lossy(&buf).into_owned()
}

/// Check that every action is in `0..num_actions`; the error names the env and the value.
pub fn validate_actions(
    actions: &[i64],
    env_ids: impl Iterator<Item = usize>,
    num_actions: usize,
) -> Result<(), PoolError> {
    for (a, env) in actions.iter().zip(env_ids) {
        if *a < 0 || *a as u64 >= num_actions as u64 {
            return Err(PoolError::BadAction {
                env,
                value: *a,
                num_actions,
            });
        }
    }
    Ok(())
}

fn status_parts(st: &ExitStatus) -> (Option<i32>, Option<i32>) {
    (st.code(), st.signal())
}

impl Pool {
    /// Start a pool: sweep stale pools, build one env locally to learn the spec, spawn the
    /// workers and wait until all are ready. Call [`Pool::reset`] or [`Pool::async_reset`]
    /// next.
    pub fn new(cfg: PoolConfig, registry: &EnvRegistry) -> Result<Pool, PoolError> {
        if cfg.num_workers == 0 || cfg.num_envs == 0 {
            return Err(PoolError::Config(
                "num_envs and num_workers must be at least 1".into(),
            ));
        }
        if !cfg.num_envs.is_multiple_of(cfg.num_workers) {
            return Err(PoolError::Config(format!(
                "num_envs ({}) must be a multiple of num_workers ({}): each worker steps the same number of envs",
                cfg.num_envs, cfg.num_workers
            )));
        }
        let epw = cfg.num_envs / cfg.num_workers;
        if let Some(b) = cfg.batch_size
            && (b == 0 || !b.is_multiple_of(epw) || b > cfg.num_envs)
        {
            return Err(PoolError::Config(format!(
                "batch_size ({b}) must be a positive multiple of the envs per worker ({epw}) and at most num_envs ({}): async batches are made of whole worker blocks",
                cfg.num_envs
            )));
        }
        if cfg.max_borrowed < 2 {
            return Err(PoolError::Config(
                "max_borrowed must be at least 2 (one sample being received, one held)".into(),
            ));
        }
        cfg.seeds.validate().map_err(PoolError::Config)?;
        let spec = registry.make(&cfg.env)?.spec();
        let layout = BlockLayout {
            envs: epw,
            obs_bytes: spec.obs_bytes(),
            final_obs: cfg.autoreset == AutoresetMode::SameStep,
        };
        rogue_gym_ipc::sweep_stale_pools(&cfg.base_dir);
        let id = PoolId::new_unique(&cfg.base_dir)?;
        id.create_dirs()?;
        let settings = ChannelSettings {
            num_workers: cfg.num_workers,
            max_borrowed: cfg.max_borrowed,
        };
        let wcfg = WorkerConfig {
            pool_name: id.name().to_string(),
            base_dir: cfg.base_dir.clone(),
            num_envs: cfg.num_envs,
            num_workers: cfg.num_workers,
            envs_per_worker: epw,
            env: cfg.env.clone(),
            seeds: cfg.seeds.clone(),
            autoreset: cfg.autoreset,
            max_borrowed: cfg.max_borrowed,
            poll_budget_us: cfg.worker_wait.poll_budget.as_micros() as u64,
            block_slice_ms: cfg.worker_wait.block_slice.as_millis() as u64,
            poll_yield: cfg.worker_wait.yield_cpu,
        };
        let config_path = id.aux_dir().join("worker.json");
        let num_envs = cfg.num_envs;
        let num_workers = cfg.num_workers;
        let mut pool = Pool {
            listener: None,
            interrupt: None,
            core: Core {
                cfg,
                spec,
                layout,
                epw,
                id,
                config_path,
                settings,
                slots: Vec::new(),
                node: None,
                ready_order: VecDeque::new(),
                cur_episode: vec![None; num_envs],
                cur_seed: vec![0; num_envs],
                batch: None,
                slot_bytes: 0,
                next_slot: 0,
                restarts: 0,
                must_reset: true,
                closed: false,
                reload_seeds: vec![false; num_workers],
                worker_config: None,
            },
        };
        // From here on, Drop cleans up whatever was created.
        pool.start(&wcfg)?;
        pool.core.worker_config = Some(wcfg);
        Ok(pool)
    }

    fn start(&mut self, wcfg: &WorkerConfig) -> Result<(), PoolError> {
        let c = &mut self.core;
        let json = serde_json::to_string(wcfg)
            .map_err(|e| PoolError::Config(format!("cannot serialize worker config: {e}")))?;
        fs::write(&c.config_path, json)
            .map_err(|e| PoolError::Io(format!("cannot write {}: {e}", c.config_path.display())))?;
        c.slot_bytes = slot_bytes(c.cfg.num_envs, c.layout.obs_bytes);
        c.batch = Some(std::sync::Arc::new(rogue_gym_ipc::SharedBuffer::create(
            &c.id,
            BATCH_BUFFER,
            BATCH_SLOTS * c.slot_bytes,
        )?));
        let node = c.id.node("sup")?;
        self.listener = Some(BlockListener::new(&node, &c.settings)?);
        for k in 0..c.cfg.num_workers {
            let ports = SupervisorPorts::new(&node, k, c.epw, &c.settings)?;
            c.slots.push(WorkerSlot {
                ports,
                child: None,
                pid: 0,
                generation: 0,
                seq: 0,
                state: SlotState::Idle,
                restarted: false,
                stderr_path: PathBuf::new(),
                target: 0,
            });
        }
        c.node = Some(node);
        for k in 0..c.cfg.num_workers {
            c.spawn(k, false)?;
        }
        self.wait_until(|c| {
            !c.slots
                .iter()
                .any(|s| matches!(s.state, SlotState::Starting { .. }))
        })
    }

    /// Replace the seed schedule and restart every env's episode count: the next reset
    /// ([`Pool::reset`], [`Pool::reset_shared`] or [`Pool::async_reset`], which you must call
    /// next) starts episode 0 of every env under `seeds`, so the run continues exactly as a
    /// fresh pool created with `seeds` would (gymnasium's `reset(seed=...)`). Outstanding
    /// async results are discarded.
    pub fn set_seeds(&mut self, seeds: SeedSchedule) -> Result<(), PoolError> {
        self.check_usable()?;
        seeds.validate().map_err(PoolError::Config)?;
        self.drain()?;
        let c = &mut self.core;
        let mut wcfg = c
            .worker_config
            .clone()
            .ok_or_else(|| PoolError::State("the pool is not started".into()))?;
        wcfg.seeds = seeds.clone();
        let json = serde_json::to_string(&wcfg)
            .map_err(|e| PoolError::Config(format!("cannot serialize worker config: {e}")))?;
        // Write then rename, so a worker (re)reading it never sees a partial file.
        let tmp = c.config_path.with_extension("json.tmp");
        fs::write(&tmp, json)
            .and_then(|_| fs::rename(&tmp, &c.config_path))
            .map_err(|e| PoolError::Io(format!("cannot write {}: {e}", c.config_path.display())))?;
        c.cfg.seeds = seeds;
        c.worker_config = Some(wcfg);
        c.cur_episode.iter_mut().for_each(|e| *e = None);
        c.reload_seeds.iter_mut().for_each(|r| *r = true);
        c.must_reset = true;
        Ok(())
    }

    /// The env spec (observation shape and dtype, actions, info names).
    pub fn spec(&self) -> &EnvSpec {
        &self.core.spec
    }
    /// Number of envs.
    pub fn num_envs(&self) -> usize {
        self.core.cfg.num_envs
    }
    /// Number of workers.
    pub fn num_workers(&self) -> usize {
        self.core.cfg.num_workers
    }
    /// Envs per worker (the async granularity).
    pub fn envs_per_worker(&self) -> usize {
        self.core.epw
    }
    /// Envs per async [`Pool::recv`].
    pub fn batch_size(&self) -> usize {
        self.core.cfg.batch_size.unwrap_or(self.core.cfg.num_envs)
    }
    /// Bytes of one observation.
    pub fn obs_bytes(&self) -> usize {
        self.core.layout.obs_bytes
    }
    /// The pool's files (name, prefix, directories).
    pub fn id(&self) -> &PoolId {
        &self.core.id
    }
    /// Current worker pids (index = worker).
    pub fn worker_pids(&self) -> Vec<u32> {
        self.core.slots.iter().map(|s| s.pid).collect()
    }
    /// Worker restarts so far.
    pub fn restarts(&self) -> u32 {
        self.core.restarts
    }
    /// The configuration.
    pub fn config(&self) -> &PoolConfig {
        &self.core.cfg
    }

    /// Install (or remove) a check run between the slices of any wait that has lasted at least
    /// 5 ms (every `PoolConfig::wait.block_slice`, 10 ms by default): if it returns `true`, the
    /// call fails with [`PoolError::Interrupted`] and the pool needs a reset (outstanding
    /// requests are abandoned and drained by the reset). Bindings use it to deliver Ctrl-C
    /// during a long wait (e.g. Python's `check_signals` with the GIL re-acquired briefly).
    pub fn set_interrupt_check(&mut self, check: Option<InterruptCheck>) {
        self.interrupt = check;
    }

    fn wait_until(&mut self, done: impl Fn(&Core) -> bool) -> Result<(), PoolError> {
        let listener = self.listener.as_ref().ok_or(PoolError::Closed)?;
        let core = &mut self.core;
        let interrupt = &mut self.interrupt;
        let policy = core.cfg.wait;
        let t0 = Instant::now();
        let out = hybrid_wait::<PoolError>(listener.listener(), &policy, None, |call| {
            if call == WaitCall::Idle {
                core.check_liveness()?;
                if let Some(check) = interrupt.as_mut()
                    && t0.elapsed() >= INTERRUPT_AFTER
                    && check()
                {
                    core.must_reset = true;
                    return Err(PoolError::Interrupted);
                }
            }
            core.poll_all()?;
            Ok(done(core))
        })?;
        debug_assert_eq!(out, WaitOutcome::Done);
        Ok(())
    }

    fn check_usable(&self) -> Result<(), PoolError> {
        if self.core.closed {
            return Err(PoolError::Closed);
        }
        Ok(())
    }

    fn check_actions(
        &self,
        actions: &[i64],
        env_ids: impl Iterator<Item = usize>,
    ) -> Result<(), PoolError> {
        validate_actions(actions, env_ids, self.core.spec.num_actions)
    }

    fn check_obs_buf(&self, obs_out: &[u8]) -> Result<(), PoolError> {
        let expected = self.core.cfg.num_envs * self.core.layout.obs_bytes;
        if obs_out.len() != expected {
            return Err(PoolError::BadBuffer {
                what: "observation buffer",
                expected,
                got: obs_out.len(),
            });
        }
        Ok(())
    }

    fn all_idle(&mut self) -> Result<(), PoolError> {
        // Respawned workers (raise policy) may still be starting.
        self.wait_until(|c| {
            !c.slots
                .iter()
                .any(|s| matches!(s.state, SlotState::Starting { .. }))
        })?;
        if self
            .core
            .slots
            .iter()
            .any(|s| !matches!(s.state, SlotState::Idle))
        {
            return Err(PoolError::State(
                "async requests are outstanding: recv() them before a sync reset/step".into(),
            ));
        }
        Ok(())
    }

    /// Wait for every outstanding request (and starting worker) and discard the results.
    fn drain(&mut self) -> Result<(), PoolError> {
        self.wait_until(|c| {
            !c.slots.iter().any(|s| {
                matches!(
                    s.state,
                    SlotState::Starting { .. } | SlotState::Pending { .. }
                )
            })
        })?;
        for s in &mut self.core.slots {
            if matches!(s.state, SlotState::Ready(_)) {
                s.state = SlotState::Idle;
            }
            s.restarted = false;
        }
        self.core.ready_order.clear();
        Ok(())
    }

    /// Sync reset: start a new episode in every env (episode index 0 at the first reset, then
    /// the next index of each env), write the observations into `obs_out`
    /// (`num_envs x obs_bytes`, env-major) and the per-env arrays into `out`. Results of
    /// outstanding async requests (or of a step interrupted by an error) are discarded.
    pub fn reset(&mut self, obs_out: &mut [u8], out: &mut BatchOutput) -> Result<(), PoolError> {
        self.check_usable()?;
        self.check_obs_buf(obs_out)?;
        self.drain()?;
        for k in 0..self.core.slots.len() {
            self.core.send_reset(k, 0)?;
        }
        self.core.must_reset = false;
        self.gather_all(Some(obs_out), out)
    }

    /// Sync step: `actions[i]` for env `i` (all envs). Writes observations into `obs_out`
    /// (`num_envs x obs_bytes`, env-major; one memcpy per worker block) and per-env arrays into
    /// `out`. See [`AutoresetMode`] for what a step after/at an episode end returns.
    pub fn step(
        &mut self,
        actions: &[i64],
        obs_out: &mut [u8],
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        self.check_usable()?;
        if actions.len() != self.core.cfg.num_envs {
            return Err(PoolError::BadActionsLength {
                expected: self.core.cfg.num_envs,
                got: actions.len(),
            });
        }
        self.check_actions(actions, 0..actions.len())?;
        self.check_obs_buf(obs_out)?;
        if self.core.must_reset {
            return Err(PoolError::State(
                "call reset() before step() (after creation or after a worker failure)".into(),
            ));
        }
        self.all_idle()?;
        let epw = self.core.epw;
        for k in 0..self.core.slots.len() {
            self.core
                .send_step(k, &actions[k * epw..(k + 1) * epw], 0)?;
        }
        self.gather_all(Some(obs_out), out)
    }

    /// Like [`Pool::reset`], but the workers write the observations straight into the next
    /// slot of the pool's shared batch buffer (no copy at all); returns the slot index for
    /// [`Pool::shared_obs`].
    pub fn reset_shared(&mut self, out: &mut BatchOutput) -> Result<usize, PoolError> {
        self.check_usable()?;
        self.drain()?;
        let slot = self.core.next_slot;
        for k in 0..self.core.slots.len() {
            self.core.send_reset(k, slot as u32 + 1)?;
        }
        self.core.must_reset = false;
        self.gather_all(None, out)?;
        self.core.next_slot = (slot + 1) % BATCH_SLOTS;
        Ok(slot)
    }

    /// Partial sync reset (gymnasium's `reset(options={"reset_mask": mask})`), into the next
    /// shared batch slot like [`Pool::reset_shared`]; returns the slot.
    ///
    /// * Envs with `mask[i] == true` start their next scheduled episode (episode index + 1, its
    ///   seed from the schedule), exactly as a full reset would start it for them, so
    ///   trajectories stay independent of the worker count.
    /// * Envs with `mask[i] == false` keep their state (an episode that ended in NEXT_STEP mode
    ///   is still autoreset by the next step); their current observation is re-written into
    ///   the slot by the worker ([`crate::Env::observe`]), and their row in `out` describes
    ///   their current episode with reward 0 and no flags.
    ///
    /// Needs a full reset first (after creation, [`Pool::set_seeds`] or a worker failure
    /// under [`FailurePolicy::Raise`]) and no outstanding async requests (sync only; there is
    /// no async partial reset). A worker restarted during the call resets all its envs (they
    /// report `restarted`).
    pub fn reset_envs(&mut self, mask: &[bool], out: &mut BatchOutput) -> Result<usize, PoolError> {
        let slot = self.core.next_slot;
        self.reset_masked(mask, slot as u32 + 1, None, out)?;
        self.core.next_slot = (slot + 1) % BATCH_SLOTS;
        Ok(slot)
    }

    /// [`Pool::reset_envs`], with the observations copied into `obs_out` (`num_envs x
    /// obs_bytes`) like [`Pool::reset`].
    pub fn reset_envs_into(
        &mut self,
        mask: &[bool],
        obs_out: &mut [u8],
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        self.check_obs_buf(obs_out)?;
        self.reset_masked(mask, 0, Some(obs_out), out)
    }

    fn reset_masked(
        &mut self,
        mask: &[bool],
        target: u32,
        obs_out: Option<&mut [u8]>,
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        self.check_usable()?;
        if mask.len() != self.core.cfg.num_envs {
            return Err(PoolError::BadBuffer {
                what: "reset mask",
                expected: self.core.cfg.num_envs,
                got: mask.len(),
            });
        }
        if self.core.must_reset {
            return Err(PoolError::State(
                "a partial reset needs every env started: call a full reset() first (after creation, set_seeds or a worker failure)".into(),
            ));
        }
        self.all_idle()?;
        for k in 0..self.core.slots.len() {
            self.core.send_reset_masked(k, target, Some(mask))?;
        }
        self.gather_all(obs_out, out)
    }

    /// Like [`Pool::step`], but the workers write the observations straight into the next
    /// slot of the pool's shared batch buffer (zero-copy sync step); returns the slot index
    /// for [`Pool::shared_obs`]. Slots alternate (double buffering): the observations of slot
    /// `s` stay unchanged until the second `*_shared` call after the one that returned `s`.
    pub fn step_shared(
        &mut self,
        actions: &[i64],
        out: &mut BatchOutput,
    ) -> Result<usize, PoolError> {
        self.check_usable()?;
        if actions.len() != self.core.cfg.num_envs {
            return Err(PoolError::BadActionsLength {
                expected: self.core.cfg.num_envs,
                got: actions.len(),
            });
        }
        self.check_actions(actions, 0..actions.len())?;
        if self.core.must_reset {
            return Err(PoolError::State(
                "call reset() before step() (after creation or after a worker failure)".into(),
            ));
        }
        self.all_idle()?;
        let epw = self.core.epw;
        let slot = self.core.next_slot;
        for k in 0..self.core.slots.len() {
            self.core
                .send_step(k, &actions[k * epw..(k + 1) * epw], slot as u32 + 1)?;
        }
        self.gather_all(None, out)?;
        self.core.next_slot = (slot + 1) % BATCH_SLOTS;
        Ok(slot)
    }

    /// The observations of shared batch slot `slot` (`num_envs x obs_bytes`, env-major,
    /// 64-byte aligned). See [`Pool::step_shared`] for when they are valid.
    pub fn shared_obs(&self, slot: usize) -> &[u8] {
        let n = self.core.cfg.num_envs * self.core.layout.obs_bytes;
        match &self.core.batch {
            // SAFETY: the slot lies inside the mapping. Workers write a slot only during a
            // `*_shared` call, which needs `&mut self`: none runs while this borrow lives.
            Some(b) if slot < BATCH_SLOTS => unsafe {
                std::slice::from_raw_parts(b.as_ptr().add(slot * self.core.slot_bytes), n)
            },
            _ => &[],
        }
    }

    /// The shared batch buffer itself: slot `s` starts at byte `s * shared_slot_bytes()`.
    /// Holding this `Arc` keeps the mapping valid even after [`Pool::close`] (e.g. as the base
    /// object of numpy views); `None` after close.
    pub fn shared_buffer(&self) -> Option<std::sync::Arc<rogue_gym_ipc::SharedBuffer>> {
        self.core.batch.clone()
    }

    /// Distance in bytes between two shared batch slots.
    pub fn shared_slot_bytes(&self) -> usize {
        self.core.slot_bytes
    }

    /// Raw pointer to shared batch slot `slot` (for zero-copy views in other languages; keep
    /// [`Pool::shared_buffer`] alive with the view). Null after `close`.
    pub fn shared_obs_ptr(&self, slot: usize) -> *const u8 {
        match &self.core.batch {
            Some(b) if slot < BATCH_SLOTS => {
                // SAFETY: the offset stays inside the mapping.
                unsafe { b.as_ptr().add(slot * self.core.slot_bytes) }
            }
            _ => std::ptr::null(),
        }
    }

    fn gather_all(
        &mut self,
        mut obs_out: Option<&mut [u8]>,
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        // Copy each block as soon as it arrives, overlapping with the other workers' steps.
        let w = self.core.slots.len();
        let blk_bytes = self.core.epw * self.core.layout.obs_bytes;
        let mut blocks: Vec<Option<Block>> = (0..w).map(|_| None).collect();
        let mut got = 0;
        while got < w {
            self.wait_until(|c| !c.ready_order.is_empty())?;
            while let Some(k) = self.core.ready_order.pop_front() {
                let b = self.core.take_block(k)?;
                if let Some(o) = obs_out.as_deref_mut() {
                    o[k * blk_bytes..(k + 1) * blk_bytes].copy_from_slice(b.obs());
                }
                blocks[k] = Some(b);
                got += 1;
            }
        }
        out.clear();
        let n_info = self.core.spec.info_names.len();
        let batch = Batch {
            blocks: blocks.into_iter().flatten().collect(),
        };
        batch.fill_append(n_info, out);
        Ok(())
    }

    /// Async: reset every env (as [`Pool::reset`]; outstanding results are discarded); collect
    /// the results with [`Pool::recv`].
    pub fn async_reset(&mut self) -> Result<(), PoolError> {
        self.check_usable()?;
        self.drain()?;
        for k in 0..self.core.slots.len() {
            self.core.send_reset(k, 0)?;
        }
        self.core.must_reset = false;
        Ok(())
    }

    /// Async: send actions to envs. `env_ids` must consist of whole worker blocks, each in
    /// order (`k*epw .. (k+1)*epw`), whose previous result has been received; `actions[r]` is
    /// for `env_ids[r]`.
    pub fn send(&mut self, actions: &[i64], env_ids: &[usize]) -> Result<(), PoolError> {
        self.check_usable()?;
        if actions.len() != env_ids.len() {
            return Err(PoolError::BadActionsLength {
                expected: env_ids.len(),
                got: actions.len(),
            });
        }
        if self.core.must_reset {
            return Err(PoolError::State(
                "call async_reset() before send() (after creation or after a worker failure)"
                    .into(),
            ));
        }
        self.check_actions(actions, env_ids.iter().copied())?;
        let epw = self.core.epw;
        if !env_ids.len().is_multiple_of(epw) {
            return Err(PoolError::State(format!(
                "send() got {} env ids; they must form whole worker blocks of {epw} envs",
                env_ids.len()
            )));
        }
        let mut workers = Vec::with_capacity(env_ids.len() / epw);
        for chunk in env_ids.chunks(epw) {
            let k = chunk[0] / epw;
            if !chunk[0].is_multiple_of(epw)
                || k >= self.core.slots.len()
                || chunk.iter().enumerate().any(|(j, &e)| e != k * epw + j)
            {
                return Err(PoolError::State(format!(
                    "send() env ids {chunk:?} do not form a worker block: give each block's ids in order, k*{epw}..(k+1)*{epw}"
                )));
            }
            if !matches!(self.core.slots[k].state, SlotState::Idle) || workers.contains(&k) {
                return Err(PoolError::State(format!(
                    "send() to envs {}..{} whose previous request has not been received yet: recv() first",
                    k * epw,
                    (k + 1) * epw
                )));
            }
            workers.push(k);
        }
        for (r, &k) in workers.iter().enumerate() {
            self.core
                .send_step(k, &actions[r * epw..(r + 1) * epw], 0)?;
        }
        Ok(())
    }

    /// Async: wait for the next `batch_size` envs (whole blocks, in arrival order) and hand
    /// their blocks over (zero-copy; see [`Block`] for lifetimes).
    pub fn recv(&mut self) -> Result<Batch, PoolError> {
        self.check_usable()?;
        let want = self.batch_size() / self.core.epw;
        let outstanding = self
            .core
            .slots
            .iter()
            .filter(|s| !matches!(s.state, SlotState::Idle))
            .count();
        if outstanding < want {
            return Err(PoolError::State(format!(
                "recv() needs {want} outstanding worker blocks but only {outstanding} are: send() actions (or async_reset()) first"
            )));
        }
        self.wait_until(|c| c.ready_order.len() >= want)?;
        let mut blocks = Vec::with_capacity(want);
        for _ in 0..want {
            let Some(k) = self.core.ready_order.pop_front() else {
                break;
            };
            blocks.push(self.core.take_block(k)?);
        }
        Ok(Batch { blocks })
    }

    /// Stop the workers and remove every file of the pool (`/dev/shm` and directories).
    /// Idempotent; also run by `Drop`. Blocks still held by the caller stay readable.
    pub fn close(&mut self) -> Result<(), PoolError> {
        if self.core.closed {
            return Ok(());
        }
        self.core.closed = true;
        let c = &mut self.core;
        for s in &c.slots {
            if s.child.is_some() {
                let _ = s.ports.send_cmd(u64::MAX, CMD_CLOSE, 0, |_| {});
            }
        }
        let deadline = Instant::now() + Duration::from_millis(300);
        for s in &mut c.slots {
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
        c.ready_order.clear();
        c.slots.clear();
        self.listener = None;
        c.node = None;
        c.batch = None;
        rogue_gym_ipc::remove_pool_files(&c.id)?;
        Ok(())
    }
}

impl Drop for Pool {
    fn drop(&mut self) {
        let _ = self.close();
    }
}

impl Batch {
    fn fill_append(&self, n_info: usize, out: &mut BatchOutput) {
        for b in &self.blocks {
            let fin = b.final_obs();
            let ob = b.layout.obs_bytes;
            for j in 0..b.layout.envs {
                out.push(
                    b.env_start + j,
                    &b.record(j),
                    n_info,
                    fin.map(|f| &f[j * ob..(j + 1) * ob]),
                );
            }
        }
    }
}

impl Core {
    fn env_range(&self, k: usize) -> Range<usize> {
        k * self.epw..(k + 1) * self.epw
    }

    fn spawn(&mut self, k: usize, then_reset: bool) -> Result<(), PoolError> {
        let generation = self.slots[k].generation;
        let log = self.id.aux_dir().join(format!("w{k}.g{generation}.stderr"));
        let file = fs::File::create(&log)
            .map_err(|e| PoolError::Io(format!("cannot create {}: {e}", log.display())))?;
        let w = &self.cfg.worker;
        let child = Command::new(&w.program)
            .args(&w.args)
            .arg("--config")
            .arg(&self.config_path)
            .args(["--index", &k.to_string()])
            .args(["--generation", &generation.to_string()])
            .args(["--ppid", &std::process::id().to_string()])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(file)
            .spawn()
            .map_err(|e| PoolError::StartFailed {
                worker: k,
                reason: format!(
                    "cannot execute {} {:?}: {e}; check the worker command (program and leading args)",
                    w.program.display(),
                    w.args
                ),
                stderr_tail: String::new(),
            })?;
        let s = &mut self.slots[k];
        s.pid = child.id();
        s.child = Some(child);
        s.stderr_path = log;
        s.state = SlotState::Starting {
            since: Instant::now(),
            then_reset,
        };
        Ok(())
    }

    fn send_reset(&mut self, k: usize, target: u32) -> Result<(), PoolError> {
        self.send_reset_masked(k, target, None)
    }

    /// Reset command to worker `k`; with `mask` (the whole pool's), envs whose entry is false
    /// get [`KEEP_EPISODE`] (keep state, re-write the current observation).
    fn send_reset_masked(
        &mut self,
        k: usize,
        target: u32,
        mask: Option<&[bool]>,
    ) -> Result<(), PoolError> {
        let range = self.env_range(k);
        let eps: Vec<u64> = range
            .map(|i| {
                if mask.is_some_and(|m| !m[i]) {
                    KEEP_EPISODE
                } else {
                    self.cur_episode[i].map_or(0, |e| e + 1)
                }
            })
            .collect();
        let reload = if std::mem::take(&mut self.reload_seeds[k]) {
            RELOAD_SEEDS
        } else {
            0
        };
        let s = &mut self.slots[k];
        s.seq += 1;
        s.target = target;
        s.ports.send_cmd(
            s.seq,
            CMD_RESET | (target << TARGET_SHIFT) | reload,
            eps.len(),
            |p| p.copy_from_slice(&eps),
        )?;
        s.state = SlotState::Pending {
            since: Instant::now(),
        };
        Ok(())
    }

    fn send_step(&mut self, k: usize, actions: &[i64], target: u32) -> Result<(), PoolError> {
        let s = &mut self.slots[k];
        s.seq += 1;
        s.target = target;
        let kind = CMD_STEP | (target << TARGET_SHIFT);
        s.ports.send_cmd(s.seq, kind, actions.len(), |p| {
            for (d, a) in p.iter_mut().zip(actions) {
                *d = *a as u64;
            }
        })?;
        s.state = SlotState::Pending {
            since: Instant::now(),
        };
        Ok(())
    }

    fn take_block(&mut self, k: usize) -> Result<Block, PoolError> {
        let s = &mut self.slots[k];
        match std::mem::replace(&mut s.state, SlotState::Idle) {
            SlotState::Ready(sample) => {
                let restarted = std::mem::take(&mut s.restarted);
                Ok(Block {
                    worker: k,
                    env_start: k * self.epw,
                    layout: self.layout,
                    restarted,
                    sample,
                })
            }
            other => {
                s.state = other;
                Err(PoolError::State(format!("worker {k} has no block ready")))
            }
        }
    }

    /// Take every available block of starting and pending workers.
    fn poll_all(&mut self) -> Result<(), PoolError> {
        for k in 0..self.slots.len() {
            loop {
                let s = &mut self.slots[k];
                if !matches!(
                    s.state,
                    SlotState::Starting { .. } | SlotState::Pending { .. }
                ) {
                    break;
                }
                let Some(sample) = s.ports.try_recv()? else {
                    break;
                };
                let h = *sample.user_header();
                if h.generation != s.generation {
                    continue; // from a dead incarnation
                }
                match (&s.state, h.kind) {
                    (SlotState::Starting { then_reset, .. }, BLOCK_READY) => {
                        if *then_reset {
                            drop(sample);
                            // Same observation target as the interrupted command.
                            let target = s.target;
                            self.send_reset(k, target)?;
                        } else {
                            s.state = SlotState::Idle;
                        }
                    }
                    (SlotState::Pending { .. }, BLOCK_DATA) if h.seq == s.seq => {
                        let same_step = self.cfg.autoreset == AutoresetMode::SameStep;
                        for j in 0..self.epw {
                            let r = self.layout.record(sample.payload(), j);
                            let done = r.terminated() || r.truncated();
                            // In SAME_STEP mode a finished env already started the next
                            // episode (not yet reported).
                            self.cur_episode[k * self.epw + j] =
                                Some(r.episode + u64::from(same_step && done));
                            self.cur_seed[k * self.epw + j] = r.seed;
                        }
                        self.slots[k].state = SlotState::Ready(sample);
                        self.ready_order.push_back(k);
                    }
                    _ => {} // stale answer: drop it
                }
            }
        }
        Ok(())
    }

    /// Detect dead and hung workers; restart them or fail per policy.
    fn check_liveness(&mut self) -> Result<(), PoolError> {
        for k in 0..self.slots.len() {
            let range = self.env_range(k);
            let s = &mut self.slots[k];
            let (since, starting) = match s.state {
                SlotState::Starting { since, .. } => (since, true),
                SlotState::Pending { since } => (since, false),
                _ => continue,
            };
            let exited = match s.child.as_mut() {
                Some(ch) => ch.try_wait().ok().flatten(),
                None => None,
            };
            let limit = if starting {
                Some(self.cfg.start_timeout)
            } else {
                self.cfg.step_timeout
            };
            let hung = exited.is_none() && limit.is_some_and(|l| since.elapsed() > l);
            if exited.is_none() && !hung {
                continue;
            }
            if hung && let Some(ch) = s.child.as_mut() {
                let _ = ch.kill();
            }
            let status = match (exited, s.child.as_mut()) {
                (Some(st), _) => Some(st),
                (None, Some(ch)) => ch.wait().ok(),
                (None, None) => None,
            };
            s.child = None;
            let (code, signal) = status.as_ref().map(status_parts).unwrap_or((None, None));
            let tail = stderr_tail(&s.stderr_path);
            if starting {
                let reason = if hung {
                    format!(
                        "not ready within start_timeout {:?} (killed)",
                        self.cfg.start_timeout
                    )
                } else {
                    match (signal, code) {
                        (Some(sig), _) => {
                            format!(
                                "killed by signal {sig} ({}) during start-up",
                                signal_name(sig)
                            )
                        }
                        (None, Some(c)) => format!("exited with code {c} during start-up"),
                        _ => "died during start-up".into(),
                    }
                };
                return Err(PoolError::StartFailed {
                    worker: k,
                    reason,
                    stderr_tail: tail,
                });
            }
            let failure = WorkerFailure {
                worker: k,
                env_ids: range.clone(),
                pid: s.pid,
                cause: if hung {
                    FailureCause::Hung(limit.unwrap_or_default())
                } else {
                    FailureCause::Died
                },
                exit_code: code,
                signal,
                seeds: self.cur_seed[range.clone()].to_vec(),
                stderr_tail: tail,
            };
            self.handle_failure(k, failure)?;
        }
        Ok(())
    }

    fn handle_failure(&mut self, k: usize, failure: WorkerFailure) -> Result<(), PoolError> {
        rogue_gym_ipc::cleanup_dead_nodes(&self.id)?;
        // Drop whatever the dead incarnation left in the queue.
        while self.slots[k].ports.try_recv()?.is_some() {}
        self.ready_order.retain(|&w| w != k);
        self.slots[k].generation += 1;
        match self.cfg.on_worker_failure {
            FailurePolicy::Raise => {
                self.spawn(k, false)?;
                self.must_reset = true;
                Err(PoolError::WorkerFailed(Box::new(failure)))
            }
            FailurePolicy::Restart => {
                self.restarts += 1;
                if self.restarts > self.cfg.max_restarts {
                    return Err(PoolError::RestartBudgetExceeded {
                        max_restarts: self.cfg.max_restarts,
                        last: Box::new(failure),
                    });
                }
                self.slots[k].restarted = true;
                self.spawn(k, true)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_send<T: Send>() {}

    #[test]
    fn actions_are_validated_with_env_and_value() {
        assert!(validate_actions(&[0, 10, 5], 0..3, 11).is_ok());
        let e = validate_actions(&[0, 11], 4..6, 11).unwrap_err();
        assert_eq!(
            e.to_string(),
            "env 5: action 11 is out of range; valid actions are 0..11"
        );
        assert!(matches!(
            validate_actions(&[-1], 0..1, 11),
            Err(PoolError::BadAction {
                env: 0,
                value: -1,
                ..
            })
        ));
    }

    #[test]
    fn pool_and_block_are_send() {
        assert_send::<Pool>();
        assert_send::<Block>();
        assert_send::<Batch>();
    }
}
