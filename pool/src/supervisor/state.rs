//! The supervisor's state, grouped by concern: the call in flight, the async API, worker
//! failures and recycling ([`super::Supervisor`] holds one of each).

use std::time::{Duration, Instant};

use super::stepping::SentCall;
use crate::error::{PoolError, WorkerFailure};

/// The call in progress: its bound, its failures so far, and a whole-batch call sent and not
/// yet collected.
pub(super) struct CallInFlight {
    /// When the current call began, and when a worker first failed during it: its bound
    /// ([`super::Supervisor::call_deadline`]) counts from these.
    pub(super) started: Instant,
    pub(super) failed_at: Option<Instant>,
    /// Failures of the current call (env errors, workers lost under the raise policy), raised
    /// together once no worker still owes the call an answer.
    pub(super) faults: Vec<PoolError>,
    /// While draining stale answers before a reset: env errors of abandoned commands are
    /// dropped, not raised (the reset starts those envs afresh anyway); lost workers are not.
    pub(super) discard_faults: bool,
    /// The whole-batch call sent and not yet collected ([`crate::Pool::send_step`],
    /// [`crate::Pool::wait`]).
    pub(super) sent: Option<SentCall>,
    /// When the latest answer of the whole-batch call in flight was published (the workers'
    /// stamp, `CLOCK_MONOTONIC`, ns).
    pub(super) ready_ns: u64,
    /// How long the workers took to answer the last whole-batch call they were waited for:
    /// the next wait sleeps through most of it and polls for the rest.
    pub(super) expected_answer: Option<Duration>,
    /// The wait policy of the wait in progress, when it differs from the pool's.
    pub(super) wait_now: Option<rogue_gym_ipc::WaitPolicy>,
}

impl CallInFlight {
    /// A call in flight from now on: no failure, nothing sent.
    pub(super) fn new() -> Self {
        CallInFlight {
            started: Instant::now(),
            failed_at: None,
            faults: Vec::new(),
            discard_faults: false,
            sent: None,
            ready_ns: 0,
            expected_answer: None,
            wait_now: None,
        }
    }
}

/// The EnvPool-style async API ([`super::async_api`]).
pub(super) struct AsyncState {
    /// Its envs ([`super::async_envs`]).
    pub(super) envs: super::async_envs::AsyncEnvs,
    /// In use (from `async_reset` or a `send` to the next reset).
    pub(super) on: bool,
    /// Workers host a vector env each ([`crate::EnvRegistry::builds_blocks`]): it sends whole
    /// worker blocks only.
    pub(super) whole_blocks: bool,
}

impl AsyncState {
    /// Not in use yet, over `envs`.
    pub(super) fn new(envs: super::async_envs::AsyncEnvs, whole_blocks: bool) -> Self {
        AsyncState {
            envs,
            on: false,
            whole_blocks,
        }
    }
}

/// Worker failures over the pool's life, and what they leave to do.
pub(super) struct Failures {
    /// Worker restarts, and deaths and hangs (under either policy).
    pub(super) restarts: u32,
    pub(super) deaths: u32,
    /// The last worker failure, for the report of a call that outlived its bound.
    pub(super) last_failure: Option<Box<WorkerFailure>>,
    /// The envs must be reset before they step (at the start, after a failure).
    pub(super) must_reset: bool,
}

impl Failures {
    /// None yet; the envs must be reset first.
    pub(super) fn new() -> Self {
        Failures {
            restarts: 0,
            deaths: 0,
            last_failure: None,
            must_reset: true,
        }
    }
}

/// Workers replaced by plan ([`super::recycling`]).
#[derive(Default)]
pub(super) struct Recycling {
    /// The envs whose worker was replaced by plan during the last call
    /// ([`crate::Pool::recycled_envs`]).
    pub(super) replaced_envs: Vec<usize>,
}
