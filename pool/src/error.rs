//! The pool's errors and the report on a failed worker.

use std::ops::Range;
use std::time::Duration;

use rogue_gym_ipc::IpcError;

use serde::{Deserialize, Serialize};

use crate::env::EnvError;

/// An env's failure on a command, as the worker reports it: which env, during what, and the
/// env's own message (for hosted Python envs, the encoded exception).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct EnvFault {
    /// Global env id.
    pub env: u64,
    /// What the env was doing, e.g. `step (episode 3, seed 7, step 12)`.
    pub context: String,
    /// The env's error message.
    pub message: String,
}

impl EnvFault {
    /// The fault of env `env` (global id) during `context`, with the error's `message`.
    pub(crate) fn new(
        env: u64,
        context: impl Into<String>,
        message: impl std::fmt::Display,
    ) -> Self {
        EnvFault {
            env,
            context: context.into(),
            message: message.to_string(),
        }
    }
    /// Write the report as a private file (then rename, so a reader never sees a partial
    /// file).
    pub(crate) fn write(&self, path: &std::path::Path) -> Result<(), String> {
        let json =
            serde_json::to_string(self).map_err(|e| format!("cannot encode {self:?}: {e}"))?;
        rogue_gym_ipc::private::write_private_file(path, json.as_bytes()).map_err(|e| e.to_string())
    }
    /// Read (and remove) a report; it must be a private file of this user.
    pub(crate) fn take(path: &std::path::Path) -> Result<EnvFault, String> {
        let data = rogue_gym_ipc::private::read_private_file(path).map_err(|e| e.to_string())?;
        let _ = std::fs::remove_file(path);
        serde_json::from_slice(&data).map_err(|e| format!("bad env fault report: {e}"))
    }
}

/// Why a worker failed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FailureCause {
    /// The process exited or was killed.
    Died,
    /// It did not answer within the step timeout and was killed.
    Hung(Duration),
    /// It did not say it was ready within the start timeout and was killed.
    NotReady(Duration),
    /// It wrote a value outside its bounds into shared memory (this says which), so it was
    /// killed: what it wrote is never used.
    Corrupt(String),
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
    /// It failed while starting (at the pool's start or in a restart), before it was ready.
    pub starting: bool,
}

impl std::fmt::Display for WorkerFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "worker {} (pid {}, envs {}..{}) ",
            self.worker, self.pid, self.env_ids.start, self.env_ids.end
        )?;
        match &self.cause {
            FailureCause::Hung(t) => write!(
                f,
                "hung: no answer within step_timeout {t:?}, so it was killed"
            )?,
            FailureCause::NotReady(t) => write!(
                f,
                "was not ready within start_timeout {t:?}, so it was killed"
            )?,
            FailureCause::Corrupt(what) => write!(
                f,
                "wrote a value out of bounds into the pool's shared memory ({what}), so it was \
                 killed: a bug of the worker or of code it runs (an env's C extension)"
            )?,
            FailureCause::Died => match (self.signal, self.exit_code) {
                (Some(s), _) => write!(f, "was killed by signal {s} ({})", signal_name(s))?,
                (None, Some(c)) => write!(f, "exited with code {c}")?,
                _ => write!(f, "died")?,
            },
        }
        if self.starting && self.cause == FailureCause::Died {
            write!(f, " while starting")?;
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

fn several_tail(all: &[PoolError]) -> String {
    match all.len() {
        0 | 1 => String::new(),
        n => format!(
            "\n({} more failure{} in the same call: {})",
            n - 1,
            if n == 2 { "" } else { "s" },
            all[1..]
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join("; ")
        ),
    }
}

impl PoolError {
    /// One error for the failures of one call: the only one, or [`PoolError::Several`].
    pub(crate) fn collected(mut all: Vec<PoolError>) -> Option<PoolError> {
        match all.len() {
            0 => None,
            1 => all.pop(),
            _ => Some(PoolError::Several(all)),
        }
    }
}

fn describe_waiting(waiting: &[(usize, &'static str)]) -> String {
    let parts: Vec<String> = waiting
        .iter()
        .map(|(k, what)| format!("worker {k} ({what})"))
        .collect();
    match parts.len() {
        0 => "the workers".into(),
        _ => parts.join(", "),
    }
}

pub(crate) fn signal_name(s: i32) -> &'static str {
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
    #[error("env {env}: {}", crate::env::action_out_of_range(value, *num_actions))]
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
    /// A worker was killed by SIGBUS: a write to shared memory that the filesystem could not
    /// back, most likely because `/dev/shm` is full. It is not restarted in a loop.
    #[error(
        "probably out of shared memory: /dev/shm has {}, and this pool needs {} there. Give the \
         container more shared memory (docker run --shm-size=1g, or --ipc=host), or use fewer \
         envs or smaller observations; python -m rogue_gym.doctor checks a machine. {failure}",
        room.map(|r| format!("{} free of {}", rogue_gym_ipc::error::mib(r.free), rogue_gym_ipc::error::mib(r.size))).unwrap_or_else(|| "its size is unknown".into()),
        rogue_gym_ipc::error::mib(*need)
    )]
    OutOfSharedMemory {
        /// The worker's failure (signal 7).
        failure: Box<WorkerFailure>,
        /// Bytes the pool needs in /dev/shm.
        need: u64,
        /// The filesystem's size and free space when the worker died.
        room: Option<rogue_gym_ipc::ShmRoom>,
    },
    /// A worker died or hung (policy `raise`). The pool respawned it: call `reset` to go on.
    #[error("{0}; call reset() to continue")]
    WorkerFailed(Box<WorkerFailure>),
    /// An env failed on a command (its reset or step returned an error, or it got a bad
    /// action). The worker is fine and keeps its envs; call `reset` to go on.
    #[error("env {} failed in {} (worker {worker}, pid {pid}): {}; call reset() to continue", fault.env, fault.context, fault.message)]
    EnvFailed {
        /// The report.
        fault: Box<EnvFault>,
        /// Index of the env's worker.
        worker: usize,
        /// Its process id.
        pid: u32,
    },
    /// Too many restarts.
    #[error("restart budget exhausted ({max_restarts} restarts); last failure: {last}")]
    RestartBudgetExceeded {
        /// The budget.
        max_restarts: u32,
        /// The failure that exceeded it.
        last: Box<WorkerFailure>,
    },
    /// The interrupt check ([`crate::Pool::set_interrupt_check`]) asked to abort a wait. Outstanding
    /// requests are abandoned: call a reset to go on.
    #[error("interrupted while waiting for the workers; call reset() to continue")]
    Interrupted,
    /// A call reached its bound ([`crate::Pool::call_bound`]) while lost workers were still
    /// coming back (a crash storm, a worker that dies at every start). The pool goes on
    /// restarting them; call `reset` to go on.
    #[error("{} could not be brought back within this call's bound of {bound}: {deaths} worker failure{} so far ({restarts} of {max_restarts} restarts used){}. The pool goes on restarting them: call reset() to continue (it waits at most the same bound). If this repeats, something keeps killing the workers or they cannot start: see the end of their stderr, the kernel log (the OOM killer), or raise start_timeout", describe_waiting(waiting), if *deaths == 1 { "" } else { "s" }, last.as_ref().map(|l| format!("; last failure: {l}")).unwrap_or_default())]
    NotBackInTime {
        /// The workers the call still waited for, and what each was doing.
        waiting: Vec<(usize, &'static str)>,
        /// The bound, with its formula.
        bound: String,
        /// Worker failures over the pool's life.
        deaths: u32,
        /// Restarts used.
        restarts: u32,
        /// The restart budget.
        max_restarts: u32,
        /// The last worker failure.
        last: Option<Box<WorkerFailure>>,
    },
    /// Several envs or workers failed in one call: the first failure, then the others (each
    /// an [`PoolError::EnvFailed`] or [`PoolError::WorkerFailed`]). One reset clears them all.
    #[error("{}{}", .0.first().map(ToString::to_string).unwrap_or_default(), several_tail(.0))]
    Several(Vec<PoolError>),
    /// An async `recv` with a deadline found fewer than `min_batch` envs ready at it; nothing
    /// is lost (the envs stay in flight or ready for the next `recv`).
    #[error(
        "recv() timed out: {ready} of the at least {min_batch} envs asked for were ready within {timeout:?}; nothing is lost, call recv() again"
    )]
    RecvTimeout {
        /// Envs ready at the deadline.
        ready: usize,
        /// Envs asked for at least.
        min_batch: usize,
        /// The deadline, from the call's start.
        timeout: std::time::Duration,
    },
    /// The pool is closed.
    #[error("the pool is closed")]
    Closed,
    /// File-system error on the pool's own files.
    #[error("{0}")]
    Io(String),
    /// A bug of the pool: a call panicked ([`crate::Pool::guarded`]). The pool stays usable
    /// after a reset, and `close` cleans up as ever.
    #[error("internal error of the pool (a bug: please report it): {0}; call reset() to continue")]
    Internal(String),
}
