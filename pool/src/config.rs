//! How a pool is configured: sizes, seeding, autoreset, crash policy, waiting, worker command.

use std::path::PathBuf;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use rogue_gym_ipc::WaitPolicy;

use crate::env::EnvSpec;
use crate::error::PoolError;
use crate::seeds::SeedSchedule;

/// When an env whose episode ended is reset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AutoresetMode {
    /// gymnasium/EnvPool default: the step after an episode ends ignores the env's action and
    /// returns the reset observation with reward 0 and `terminated = truncated = false`.
    #[default]
    NextStep,
    /// The step that ends an episode returns its reward and flags with the *reset* observation;
    /// the final observation is returned separately (SB3 `terminal_observation`).
    SameStep,
}

/// What to do when a worker dies or hangs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
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

/// How a pool pins its workers to cores.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CpuAffinity {
    /// Worker `k` runs on the `(offset + k)`-th core the pool's process may use, wrapping
    /// around (EnvPool's `thread_affinity_offset`).
    Offset(usize),
    /// Each worker on a core of its own that no other pool of the user holds, wherever the
    /// pools start: the user's pool ledger hands them out, and too few free cores is an error.
    Disjoint,
}

/// Configuration of a pool.
#[derive(Debug, Clone)]
pub struct PoolConfig {
    /// JSON spec of the env (its `"kind"` selects the constructor in the [`crate::EnvRegistry`]).
    pub env: Value,
    /// What the env looks like, when the caller already knows (hosted envs, whose front end
    /// has probed one); `None`: the supervisor builds one env to learn it.
    pub spec: Option<EnvSpec>,
    /// Total envs (at least `num_workers`).
    pub num_envs: usize,
    /// Worker processes; each steps a contiguous block of envs ([`crate::wire::block_range`]:
    /// blocks differ by at most one env).
    pub num_workers: usize,
    /// Envs returned by one async [`crate::Pool::recv`]: `num_envs`, or (when `num_workers` divides
    /// `num_envs`) a multiple of the envs per worker. `None`: all envs.
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
    /// Replace a worker in a planned way once it has served this many env steps (leaky envs;
    /// see [`crate::Pool`]'s recycling); `None`: never.
    pub recycle_after_steps: Option<u64>,
    /// Replace a worker in a planned way once its resident memory is above this many bytes;
    /// `None`: never.
    pub recycle_above_rss: Option<u64>,
    /// Envs that stay together on one worker, in groups of this many consecutive envs (the
    /// agents of one multi-agent env, one env each): `num_envs` must be a multiple of it and
    /// every worker gets whole groups ([`crate::wire::block_range_of`]). 1: any split.
    pub block_unit: usize,
    /// Pin the workers to cores (opt-in; [`CpuAffinity`]). `None` (the default): the kernel
    /// places them.
    pub cpu_affinity: Option<CpuAffinity>,
    /// Write the observation rows with streaming (non-temporal) stores, which bypass the
    /// cache: `Some(true)` always, `Some(false)` never, `None` (the default) when the
    /// observations of all the batch slots take more than a third of the last-level cache (the
    /// worker's `streaming` module says why).
    pub streaming_stores: Option<bool>,
    /// Slots of the shared batch buffer the synchronous `*_shared` calls write, 2 to
    /// [`crate::MAX_BATCH_SLOTS`]: 2 is double buffering; more let the caller keep several
    /// batches of observations without copying them (see [`crate::Pool::select_slot`]).
    pub batch_slots: usize,
    /// How to start a worker.
    pub worker: WorkerCommand,
    /// Supervisor's waiting policy.
    pub wait: WaitPolicy,
    /// Workers' waiting policy.
    pub worker_wait: WaitPolicy,
    /// The runtime directory that holds the pool's files: it must be a directory of this user
    /// that no one else can enter (it is created 0700 if missing). `None`:
    /// [`rogue_gym_ipc::default_runtime_dir`] (`$ROGUE_GYM_RUNTIME_DIR`, else
    /// `$XDG_RUNTIME_DIR/rogue-gym`, else `/tmp/rogue-gym-<uid>`).
    pub runtime_dir: Option<PathBuf>,
    /// Threads that step each worker's envs, for envs that wait (a socket, a remote simulator,
    /// a subprocess, a sleep): a waiting env then holds only its own thread, and in the async
    /// API with rows in place each env is answered as it finishes (`worker/concurrent.rs`).
    /// 0 (the default): one env after the other on the worker's own thread, which is faster
    /// for envs that compute. Envs of one [`crate::Env`] each only (not an
    /// [`crate::EnvBlock`]).
    pub env_threads: usize,
    /// A bad value one worker writes on purpose, for the pool's own tests of what the caller
    /// checks ([`crate::wire::sabotage`]). `None` (always, outside those tests).
    pub sabotage: Option<crate::wire::sabotage::Sabotage>,
}

impl PoolConfig {
    /// A config with defaults: NEXT_STEP autoreset, restart policy, no step timeout, 30 s start
    /// timeout, 100 restarts, 4 borrowed samples, 2 batch slots, base seed 0.
    pub fn new(env: Value, num_envs: usize, num_workers: usize, worker: WorkerCommand) -> Self {
        PoolConfig {
            env,
            spec: None,
            num_envs,
            num_workers,
            batch_size: None,
            seeds: SeedSchedule::default(),
            autoreset: AutoresetMode::NextStep,
            on_worker_failure: FailurePolicy::Restart,
            step_timeout: None,
            start_timeout: Duration::from_secs(30),
            max_restarts: 100,
            recycle_after_steps: None,
            recycle_above_rss: None,
            batch_slots: crate::BATCH_SLOTS,
            block_unit: 1,
            cpu_affinity: None,
            streaming_stores: None,
            worker,
            wait: WaitPolicy {
                poll_budget: Duration::from_micros(50),
                block_slice: Duration::from_millis(10),
                yield_cpu: true,
                sleep_first: Duration::ZERO,
            },
            worker_wait: WaitPolicy {
                poll_budget: Duration::from_micros(50),
                block_slice: Duration::from_millis(100),
                yield_cpu: true,
                sleep_first: Duration::ZERO,
            },
            runtime_dir: None,
            env_threads: 0,
            sabotage: None,
        }
    }

    /// Check the config before anything is started: counts, the layout of envs on workers
    /// (`block_unit`), `batch_size`, `batch_slots` and the seed schedule
    /// ([`PoolError::Config`] saying what is wrong and the range it must be in).
    pub fn validate(&self) -> Result<(), PoolError> {
        if self.num_workers == 0 || self.num_envs == 0 {
            return Err(PoolError::Config(
                "num_envs and num_workers must be at least 1".into(),
            ));
        }
        if self.num_workers > self.num_envs {
            return Err(PoolError::Config(format!(
                "num_workers ({}) must not exceed num_envs ({}): each worker hosts at least one env",
                self.num_workers, self.num_envs
            )));
        }
        let unit = self.block_unit;
        if unit == 0
            || !self.num_envs.is_multiple_of(unit)
            || self.num_workers > self.num_envs / unit
        {
            return Err(PoolError::Config(format!(
                "envs come in groups of {unit} that stay on one worker (block_unit): num_envs \
                 ({}) must be a multiple of it and num_workers ({}) at most num_envs / {unit}",
                self.num_envs, self.num_workers
            )));
        }
        if let Some(b) = self.batch_size
            && !(1..=self.num_envs).contains(&b)
        {
            return Err(PoolError::Config(format!(
                "batch_size ({b}) must be between 1 and num_envs ({})",
                self.num_envs
            )));
        }
        if !(2..=crate::MAX_BATCH_SLOTS).contains(&self.batch_slots) {
            return Err(PoolError::Config(format!(
                "batch_slots must be between 2 and {}, got {}",
                crate::MAX_BATCH_SLOTS,
                self.batch_slots
            )));
        }
        self.seeds
            .validate(self.num_envs as u64)
            .map_err(PoolError::Config)
    }
}
