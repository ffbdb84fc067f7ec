//! The supervisor's state, grouped by concern: the call in flight, the async API, worker
//! failures and recycling ([`super::Supervisor`] holds one of each).

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use crate::error::{PoolError, WorkerFailure};

/// The call in progress: its bound, its failures so far, and a split whole-batch call.
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
    /// The shared slot of a sync step or reset that was sent and not yet collected
    /// ([`crate::Pool::send_step_shared`], [`crate::Pool::wait_shared`]).
    pub(super) split: Option<usize>,
    /// The answers of that call taken so far.
    pub(super) collecting: Option<super::slot_answers::SlotCollect>,
    /// When the whole-batch call in flight was sent, and the same on the clock the workers
    /// stamp their answers with (`CLOCK_MONOTONIC`, ns).
    pub(super) split_sent: Instant,
    pub(super) split_sent_ns: u64,
    /// How long the workers took to answer the last whole-batch call they were waited for:
    /// the next wait sleeps through most of it and polls for the rest.
    pub(super) expected_answer: Option<Duration>,
    /// The wait policy of the wait in progress, when it differs from the pool's.
    pub(super) wait_now: Option<rogue_gym_ipc::WaitPolicy>,
}

/// The EnvPool-style async API ([`super::async_api`]).
pub(super) struct AsyncState {
    /// Its envs ([`super::async_envs`]).
    pub(super) envs: super::async_envs::AsyncEnvs,
    /// In use (from `async_reset` or a `send` to the next reset).
    pub(super) on: bool,
    /// Workers host a vector env each ([`crate::EnvRegistry::builds_blocks`]): it sends whole worker
    /// blocks only.
    pub(super) whole_blocks: bool,
    /// Workers whose answer has arrived, in the order polled.
    pub(super) ready_order: VecDeque<usize>,
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

/// Workers replaced by plan ([`super::recycling`]).
pub(super) struct Recycling {
    /// The envs whose worker was replaced by plan during the last call
    /// ([`crate::Pool::recycled_envs`]).
    pub(super) replaced_envs: Vec<usize>,
}
