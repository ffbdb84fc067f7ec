//! Live pool statistics, cheap enough to be always on.
//!
//! Each worker counts its own steps and time (inside its envs, waiting for a command,
//! publishing its answer) in its row of the pool's stats buffer: a small shared-memory file
//! that the supervisor creates and every worker maps, written with relaxed atomic adds, read by
//! [`crate::Pool::stats`] without a message. The supervisor adds what only it sees: restarts,
//! timeouts, the last failure and the info bytes that travelled beside a block.

use std::sync::atomic::{AtomicU64, Ordering};

use std::os::fd::OwnedFd;

use rogue_gym_ipc::{IpcError, SharedBuffer};

/// Name of the pool's stats buffer (`/dev/shm/<pool>stats`).
pub(crate) const STATS_BUFFER: &str = "stats";

/// What a worker counts, by position in its row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(usize)]
pub(crate) enum Counter {
    /// Env steps (and resets) served: envs of the block per command.
    EnvSteps = 0,
    /// Nanoseconds inside the envs' step/reset.
    EnvNs = 1,
    /// Nanoseconds waiting for the next command.
    WaitNs = 2,
    /// Nanoseconds publishing answers (the block, and info too long for it).
    PublishNs = 3,
    /// Step and reset commands served.
    Commands = 4,
    /// Nanoseconds the envs spent off the CPU inside their step/reset (waiting on I/O, a
    /// sleep, a lock), counted where the envs run on threads (`env_threads`).
    EnvWaitNs = 5,
}

/// The words of a worker's row that carry flow control for a worker whose envs run on threads
/// (`worker/concurrent.rs`), counted for the worker's current process: the commands it read
/// (it writes), and the answers the supervisor took (the supervisor writes). Neither side
/// sends more than the other's port holds.
const READ: usize = 6;
const TAKEN: usize = 7;

/// Counters per worker row (room to grow without changing the file's layout).
pub(crate) const ROW_WORDS: usize = 8;

/// Bytes of the stats buffer of `num_workers` workers.
pub(crate) fn buffer_bytes(num_workers: usize) -> usize {
    num_workers * ROW_WORDS * 8
}

/// The stats buffer of a pool, mapped.
#[derive(Debug)]
pub(crate) struct StatsBuffer {
    buf: SharedBuffer,
    num_workers: usize,
}

impl StatsBuffer {
    /// Create it (supervisor; zero-filled, sealed: [`SharedBuffer::create`]).
    pub(crate) fn create(num_workers: usize) -> Result<Self, IpcError> {
        let buf = SharedBuffer::create(STATS_BUFFER, buffer_bytes(num_workers))?;
        Ok(StatsBuffer { buf, num_workers })
    }

    /// Map it from the descriptor the supervisor handed down (worker).
    pub(crate) fn from_fd(fd: OwnedFd, num_workers: usize) -> Result<Self, IpcError> {
        let buf = SharedBuffer::from_fd(fd, STATS_BUFFER, buffer_bytes(num_workers))?;
        Ok(StatsBuffer { buf, num_workers })
    }

    /// The buffer (its descriptor, for the workers).
    pub(crate) fn buffer(&self) -> &SharedBuffer {
        &self.buf
    }

    fn word(&self, worker: usize, c: usize) -> &AtomicU64 {
        assert!(worker < self.num_workers && c < ROW_WORDS);
        // SAFETY: the mapping holds `num_workers * ROW_WORDS` u64 words, 8-aligned (mmap is
        // page-aligned), and lives as long as `self`; every access is atomic.
        unsafe { &*(self.buf.as_ptr() as *const AtomicU64).add(worker * ROW_WORDS + c) }
    }

    /// Add `v` to counter `c` of `worker`'s row (nothing without the `counters` feature).
    pub(crate) fn add(&self, worker: usize, c: Counter, v: u64) {
        #[cfg(feature = "counters")]
        self.word(worker, c as usize)
            .fetch_add(v, Ordering::Relaxed);
        #[cfg(not(feature = "counters"))]
        let _ = (worker, c, v);
    }

    /// Counter `c` of `worker`'s row.
    pub(crate) fn get(&self, worker: usize, c: Counter) -> u64 {
        self.word(worker, c as usize).load(Ordering::Relaxed)
    }

    /// (supervisor) One more answer taken from `worker`.
    pub(crate) fn took(&self, worker: usize) {
        self.word(worker, TAKEN).fetch_add(1, Ordering::Release);
    }

    /// (supervisor) A new process of `worker` starts: none of its answers taken, none of its
    /// commands read yet.
    pub(crate) fn new_process(&self, worker: usize) {
        self.word(worker, TAKEN).store(0, Ordering::Release);
        self.word(worker, READ).store(0, Ordering::Release);
    }

    /// (worker) One more command read.
    pub(crate) fn read_one(&self, worker: usize) {
        self.word(worker, READ).fetch_add(1, Ordering::Release);
    }

    /// (supervisor) Commands `worker`'s current process read so far.
    pub(crate) fn read(&self, worker: usize) -> u64 {
        self.word(worker, READ).load(Ordering::Acquire)
    }

    /// (worker) Answers the supervisor took from this process so far.
    pub(crate) fn taken(&self, worker: usize) -> u64 {
        self.word(worker, TAKEN).load(Ordering::Acquire)
    }
}

/// What the supervisor counts of one worker.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct SupervisorCounts {
    pub(crate) restarts: u64,
    pub(crate) recycles: u64,
    pub(crate) timeouts: u64,
    pub(crate) spilled_bytes: u64,
    pub(crate) last_failure: Option<String>,
}

/// One worker's statistics since the pool started (a worker replaced after a crash goes on
/// counting in its predecessor's row).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct WorkerStats {
    /// Env steps and resets served.
    pub env_steps: u64,
    /// Step and reset commands served.
    pub commands: u64,
    /// Nanoseconds inside the envs' step/reset (with envs on threads: their sum, so more than
    /// the time that passed).
    pub env_ns: u64,
    /// Of those, nanoseconds the envs spent off the CPU (waiting); counted where the envs run
    /// on threads.
    pub env_wait_ns: u64,
    /// Nanoseconds waiting for the next command.
    pub wait_ns: u64,
    /// Nanoseconds publishing answers.
    pub publish_ns: u64,
    /// Times the worker was replaced (died or hung).
    pub restarts: u64,
    /// Times it was replaced by plan (`recycle_after_steps`, `recycle_above_rss`), apart from
    /// `restarts`.
    pub recycles: u64,
    /// Times it did not answer within `step_timeout` (counted among `restarts`).
    pub timeouts: u64,
    /// Info bytes that did not fit the block and travelled beside it.
    pub spilled_bytes: u64,
    /// The last failure, as a sentence.
    pub last_failure: Option<String>,
}

impl StatsBuffer {
    /// Worker `k`'s statistics: its row, and what the supervisor counted of it.
    pub(crate) fn worker(&self, k: usize, sup: &SupervisorCounts) -> WorkerStats {
        WorkerStats {
            env_steps: self.get(k, Counter::EnvSteps),
            commands: self.get(k, Counter::Commands),
            env_ns: self.get(k, Counter::EnvNs),
            env_wait_ns: self.get(k, Counter::EnvWaitNs),
            wait_ns: self.get(k, Counter::WaitNs),
            publish_ns: self.get(k, Counter::PublishNs),
            restarts: sup.restarts,
            recycles: sup.recycles,
            timeouts: sup.timeouts,
            spilled_bytes: sup.spilled_bytes,
            last_failure: sup.last_failure.clone(),
        }
    }
}

/// A point in time a counter measures from: an `Instant`, or nothing (no clock read) without
/// the `counters` feature.
#[cfg(feature = "counters")]
pub(crate) type Stamp = std::time::Instant;
/// A point in time a counter measures from: nothing, without the `counters` feature.
#[cfg(not(feature = "counters"))]
#[derive(Debug, Clone, Copy)]
pub(crate) struct Stamp;

/// Now, for a counter.
#[cfg(feature = "counters")]
pub(crate) fn stamp() -> Stamp {
    std::time::Instant::now()
}

/// Now, for a counter: nothing, without the `counters` feature.
#[cfg(not(feature = "counters"))]
pub(crate) fn stamp() -> Stamp {
    Stamp
}

/// Nanoseconds since `t`, saturating.
#[cfg(feature = "counters")]
pub(crate) fn ns_since(t: Stamp) -> u64 {
    u64::try_from(t.elapsed().as_nanos()).unwrap_or(u64::MAX)
}

/// Nanoseconds since `t`: 0, without the `counters` feature.
#[cfg(not(feature = "counters"))]
pub(crate) fn ns_since(_t: Stamp) -> u64 {
    0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_are_per_worker_and_shared_between_mappings() {
        let sup = StatsBuffer::create(3).unwrap();
        let fd = sup.buffer().dup_fd().unwrap();
        let worker = StatsBuffer::from_fd(fd, 3).unwrap();
        worker.add(1, Counter::EnvSteps, 5);
        worker.add(1, Counter::EnvSteps, 2);
        worker.add(2, Counter::EnvNs, 40);
        let counts = SupervisorCounts {
            restarts: 1,
            ..Default::default()
        };
        let w1 = sup.worker(1, &counts);
        assert_eq!((w1.env_steps, w1.env_ns, w1.restarts), (7, 0, 1));
        assert_eq!(sup.worker(2, &SupervisorCounts::default()).env_ns, 40);
        assert_eq!(
            sup.worker(0, &SupervisorCounts::default()),
            WorkerStats::default()
        );
    }
}
