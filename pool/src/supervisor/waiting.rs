//! Waiting for the workers within a call's bound: the pool's one wait loop ([`Pool::wait_for`]
//! and its two simpler forms), which polls and blocks as the wait policy says, checks the
//! workers' liveness when idle, runs the interrupt check of a long wait, raises the failures
//! of a call once every worker of it has answered, and gives up a little before the call's
//! bound ([`Supervisor::call_deadline`]) with an error that says who is still missing; and
//! the policy of a whole-batch call's wait ([`Supervisor::expected_wait`]).

use std::time::{Duration, Instant};

use rogue_gym_ipc::{WaitCall, WaitOutcome, hybrid_wait};

use super::{Pool, Supervisor};
use crate::error::PoolError;

/// How long a wait must have lasted before the interrupt check runs (it runs between blocking
/// wait slices, every `PoolConfig::wait.block_slice`, so the hot path never calls it).
const INTERRUPT_AFTER: Duration = Duration::from_millis(5);

/// How long before its bound a call gives up: time to build and raise the error.
const DEADLINE_MARGIN: Duration = Duration::from_millis(20);

/// Calls shorter than this are polled for from start to end (when the caller has a core of
/// its own); longer ones are slept through for three quarters first.
const FULL_POLL: Duration = Duration::from_millis(20);

/// The longest call whose answer the caller waits for by its own policy rather than the
/// pool's: longer ones are slept through.
const EXPECTED_AT_MOST: Duration = Duration::from_millis(50);

impl Pool {
    pub(super) fn wait_until(
        &mut self,
        done: impl Fn(&Supervisor) -> bool,
    ) -> Result<(), PoolError> {
        self.wait_until_or(done, None).map(|_| ())
    }

    /// [`Pool::wait_until`], giving up at `until` too: `Ok(false)` then (nothing is abandoned;
    /// wait again later). The call's own bound still raises.
    pub(super) fn wait_until_or(
        &mut self,
        done: impl Fn(&Supervisor) -> bool,
        until: Option<Instant>,
    ) -> Result<bool, PoolError> {
        self.wait_for(|c| Ok(done(c)), until)
    }

    /// [`Pool::wait_until_or`] with a test that may act on what arrived (the async API turns
    /// blocks into ready envs and sends staged envs to workers that became free).
    pub(super) fn wait_for(
        &mut self,
        mut done: impl FnMut(&mut Supervisor) -> Result<bool, PoolError>,
        until: Option<Instant>,
    ) -> Result<bool, PoolError> {
        let listener = self.listener.as_ref().ok_or(PoolError::Closed)?;
        let sup = &mut self.sup;
        let interrupt = &mut self.interrupt;
        let policy = sup.call.wait_now.unwrap_or(sup.cfg.wait);
        let t0 = Instant::now();
        let deadline = match (sup.call_deadline(), until) {
            (Some(d), Some(u)) => Some(d.min(u)),
            (d, u) => d.or(u),
        };
        let past_deadline =
            |sup: &Supervisor| sup.call_deadline().is_some_and(|d| Instant::now() >= d);
        let out = hybrid_wait::<PoolError>(listener.listener(), &policy, deadline, |call| {
            if call == WaitCall::Idle {
                if past_deadline(sup) {
                    return Err(sup.not_back_in_time());
                }
                sup.check_liveness()?;
                if past_deadline(sup) {
                    return Err(sup.not_back_in_time());
                }
                if let Some(check) = interrupt.as_mut()
                    && t0.elapsed() >= INTERRUPT_AFTER
                    && check()
                {
                    sup.failures.must_reset = true;
                    return Err(PoolError::Interrupted);
                }
            }
            sup.poll_all()?;
            if sup.call.discard_faults {
                // Env errors of abandoned commands; a worker lost meanwhile is still news.
                sup.call
                    .faults
                    .retain(|f| !matches!(f, PoolError::EnvFailed { .. }));
            }
            if !sup.call.faults.is_empty() {
                if !sup.workers.iter().any(|s| s.state.is_pending()) {
                    // Every worker of the call has answered or was handled: raise all its
                    // failures at once, so that one reset clears them.
                    let all = std::mem::take(&mut sup.call.faults);
                    return Err(PoolError::collected(all).unwrap_or(PoolError::Interrupted));
                } else {
                    return Ok(false);
                }
            }
            done(sup)
        })?;
        match out {
            WaitOutcome::Done => Ok(true),
            WaitOutcome::TimedOut if past_deadline(&self.sup) => Err(self.sup.not_back_in_time()),
            WaitOutcome::TimedOut => Ok(false),
        }
    }
}

impl Supervisor {
    /// How to wait for the answers of the whole-batch call sent at `sent`, when the machine
    /// leaves the caller a core (`machine.rs`) and the last call took at most
    /// [`EXPECTED_AT_MOST`]: poll through a call of under [`FULL_POLL`] (for up to twice its
    /// time); for a longer one, sleep until three quarters of it have passed since the call
    /// was sent (less 200 us: the CPU is free meanwhile, and an early answer still wakes it),
    /// then poll for up to half of it (at most 2 ms), so that the answer is seen without a
    /// wake-up. `None`: the pool's own policy.
    pub(super) fn expected_wait(&mut self, sent: Instant) -> Option<rogue_gym_ipc::WaitPolicy> {
        if !self.machine.caller_polls() {
            return None;
        }
        let expected = self.call.expected_answer?;
        if expected > EXPECTED_AT_MOST {
            return None;
        }
        if expected < FULL_POLL {
            // Poll through a short call: a sleep shorter than the kernel's timer slack (50 us)
            // would only oversleep, and a wake-up costs tens of microseconds.
            return Some(rogue_gym_ipc::WaitPolicy {
                poll_budget: self.cfg.wait.poll_budget.max(expected * 2),
                ..self.cfg.wait
            });
        }
        let wake = sent + expected * 3 / 4 - Duration::from_micros(200);
        Some(rogue_gym_ipc::WaitPolicy {
            sleep_first: wake.saturating_duration_since(Instant::now()),
            poll_budget: self
                .cfg
                .wait
                .poll_budget
                .max((expected / 2).min(Duration::from_millis(2))),
            ..self.cfg.wait
        })
    }

    /// When the current call must give up (see [`Pool::call_bound`]): a little before its
    /// bound, so that the error is raised within it.
    pub(super) fn call_deadline(&self) -> Option<Instant> {
        let (from, bound) = match self.cfg.step_timeout {
            Some(t) => (self.call.started, t + self.cfg.start_timeout),
            None => (self.call.failed_at?, self.cfg.start_timeout),
        };
        Some(from + bound - (bound / 20).min(DEADLINE_MARGIN))
    }

    /// The error of a call that reached its deadline: the workers it still waits for go on
    /// coming back, and the pool needs a reset.
    pub(super) fn not_back_in_time(&mut self) -> PoolError {
        self.failures.must_reset = true;
        let waiting = self
            .workers
            .iter()
            .enumerate()
            .filter_map(|(k, s)| s.state.waiting_for().map(|what| (k, what)))
            .collect();
        let bound = match self.cfg.step_timeout {
            Some(t) => format!(
                "{:?} (step_timeout {t:?} + start_timeout {:?})",
                t + self.cfg.start_timeout,
                self.cfg.start_timeout
            ),
            None => format!(
                "start_timeout {:?} after the first worker failure (no step_timeout)",
                self.cfg.start_timeout
            ),
        };
        let err = PoolError::NotBackInTime {
            waiting,
            bound,
            deaths: self.failures.deaths,
            restarts: self.failures.restarts,
            max_restarts: self.cfg.max_restarts,
            last: self.failures.last_failure.clone(),
        };
        let mut all = vec![err];
        all.append(&mut self.call.faults);
        PoolError::collected(all).unwrap_or(PoolError::Interrupted)
    }
}
