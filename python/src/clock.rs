//! Where the caller's time goes: inside the pool's calls (waiting on the workers) or between
//! them (the caller's own code, the policy, the Python front end). Two clock reads per call.

use std::sync::atomic::AtomicU64;
#[cfg(feature = "counters")]
use std::sync::atomic::Ordering;
use std::time::Instant;

/// Time in and between the native pool's calls, since the pool started.
#[derive(Debug)]
#[cfg_attr(not(feature = "counters"), allow(dead_code))]
pub(crate) struct CallClock {
    epoch: Instant,
    /// Nanoseconds since `epoch` at which the last call ended (0: none yet).
    last_end: AtomicU64,
    /// Nanoseconds between calls.
    pub(crate) between_ns: AtomicU64,
    /// Nanoseconds inside calls.
    pub(crate) inside_ns: AtomicU64,
    /// Calls made.
    pub(crate) calls: AtomicU64,
}

impl CallClock {
    pub(crate) fn new() -> Self {
        CallClock {
            epoch: Instant::now(),
            last_end: AtomicU64::new(0),
            between_ns: AtomicU64::new(0),
            inside_ns: AtomicU64::new(0),
            calls: AtomicU64::new(0),
        }
    }

    #[cfg(feature = "counters")]
    fn now(&self) -> u64 {
        u64::try_from(self.epoch.elapsed().as_nanos())
            .unwrap_or(u64::MAX)
            .max(1)
    }

    /// A call begins: the time since the last one ended was the caller's. Returns the start.
    #[cfg(feature = "counters")]
    pub(crate) fn begin(&self) -> u64 {
        let start = self.now();
        let last = self.last_end.load(Ordering::Relaxed);
        if last != 0 {
            self.between_ns
                .fetch_add(start.saturating_sub(last), Ordering::Relaxed);
        }
        start
    }

    /// A call begins (nothing is counted without the `counters` feature).
    #[cfg(not(feature = "counters"))]
    pub(crate) fn begin(&self) -> u64 {
        0
    }

    /// The call that began at `start` ends.
    #[cfg(feature = "counters")]
    pub(crate) fn end(&self, start: u64) {
        let end = self.now();
        self.inside_ns
            .fetch_add(end.saturating_sub(start), Ordering::Relaxed);
        self.calls.fetch_add(1, Ordering::Relaxed);
        self.last_end.store(end, Ordering::Relaxed);
    }

    /// The call ends (nothing is counted without the `counters` feature).
    #[cfg(not(feature = "counters"))]
    pub(crate) fn end(&self, _start: u64) {}
}
