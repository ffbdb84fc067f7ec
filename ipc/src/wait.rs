//! Waiting: yield-poll for a bounded budget, then block on an event listener in slices.

use std::time::{Duration, Instant};

use iceoryx2::port::listener::Listener;

use crate::Svc;
use crate::error::IpcError;
use crate::error::ice;

/// How a side waits for the other: block on the event listener for `sleep_first` (an answer
/// expected no sooner: the CPU is free meanwhile, and an early event still wakes it), then
/// yield-poll for `poll_budget` (no wake-up latency when the answer comes then), then block
/// in slices of `block_slice` (between slices the caller's idle hook runs: liveness checks,
/// timeouts).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaitPolicy {
    /// How long to poll with `yield_now` before blocking. Keep it at tens of µs.
    pub poll_budget: Duration,
    /// Longest single blocking wait on the listener.
    pub block_slice: Duration,
    /// Poll with `sched_yield` between checks (`true`), or spin with a CPU pause hint
    /// (`false`; never gives the CPU away, but is still bounded by `poll_budget`).
    pub yield_cpu: bool,
    /// How long to block before polling at all (zero: poll first). A side that knows how
    /// long the other usually takes sleeps through most of it and polls for the rest.
    pub sleep_first: Duration,
}

impl Default for WaitPolicy {
    fn default() -> Self {
        WaitPolicy {
            poll_budget: Duration::from_micros(50),
            block_slice: Duration::from_millis(10),
            yield_cpu: true,
            sleep_first: Duration::ZERO,
        }
    }
}

/// Outcome of [`hybrid_wait`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaitOutcome {
    /// The callback reported completion.
    Done,
    /// The deadline passed first.
    TimedOut,
}

/// Why [`hybrid_wait`] calls its callback.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaitCall {
    /// Check for new data; return `true` when the wait is over.
    Poll,
    /// A blocking slice passed (with or without events): run liveness checks and timeouts, then
    /// poll; return `true` when the wait is over.
    Idle,
}

/// Wait until `f(WaitCall::Poll)` returns `true`: poll with `yield_now` for the policy's
/// budget, then block on `listener` (in slices of `block_slice`) and poll again after each
/// wake-up. At least once per `block_slice` of blocking, `f(WaitCall::Idle)` runs instead (use
/// it for liveness checks and timeouts); a signal interrupting the blocking wait (EINTR) is
/// not an error but also leads to an `Idle` call. An error from `f` ends the wait. `deadline` bounds the
/// whole wait. Never spins unboundedly: idle waiting uses no CPU.
pub fn hybrid_wait<E: From<IpcError>>(
    listener: &Listener<Svc>,
    policy: &WaitPolicy,
    deadline: Option<Instant>,
    mut f: impl FnMut(WaitCall) -> Result<bool, E>,
) -> Result<WaitOutcome, E> {
    if f(WaitCall::Poll)? {
        return Ok(WaitOutcome::Done);
    }
    let asleep = Instant::now();
    while asleep.elapsed() < policy.sleep_first {
        let mut slice = policy.sleep_first.saturating_sub(asleep.elapsed());
        if let Some(d) = deadline {
            slice = slice.min(d.saturating_duration_since(Instant::now()));
        }
        if slice.is_zero() {
            break;
        }
        match listener.timed_wait(|_| {}, slice) {
            Ok(_) | Err(iceoryx2::port::listener::ListenerWaitError::InterruptSignal) => {}
            Err(e) => return Err(ice("wait on event listener")(e).into()),
        }
        if f(WaitCall::Poll)? {
            return Ok(WaitOutcome::Done);
        }
    }
    let start = Instant::now();
    while start.elapsed() < policy.poll_budget {
        if policy.yield_cpu {
            std::thread::yield_now();
        } else {
            for _ in 0..64 {
                std::hint::spin_loop();
            }
        }
        if f(WaitCall::Poll)? {
            return Ok(WaitOutcome::Done);
        }
    }
    let mut last_idle = Instant::now();
    loop {
        let mut slice = policy.block_slice;
        if let Some(d) = deadline {
            let now = Instant::now();
            if now >= d {
                return Ok(WaitOutcome::TimedOut);
            }
            slice = slice.min(d - now);
        }
        // A signal (e.g. SIGINT) interrupting the blocking wait is a wake-up, not an error:
        // the Idle call below lets the caller react to it (run its signal check).
        let (n, interrupted) = match listener.timed_wait(|_| {}, slice) {
            Ok(n) => (n, false),
            Err(iceoryx2::port::listener::ListenerWaitError::InterruptSignal) => (0, true),
            Err(e) => return Err(ice("wait on event listener")(e).into()),
        };
        let call = if n == 0 || interrupted || last_idle.elapsed() >= policy.block_slice {
            last_idle = Instant::now();
            WaitCall::Idle
        } else {
            WaitCall::Poll
        };
        if f(call)? {
            return Ok(WaitOutcome::Done);
        }
    }
}
