//! The episode books: each env's current episode index and seed, written by the worker that
//! serves it, read by the supervisor only when it needs them (a reset's next episode indices,
//! a restarted worker's envs, a failure report), so that no call reads every env's answer.
//!
//! Two copies by command parity: a worker writes the books of its whole block into copy
//! `seq % 2` before it answers command `seq`, and the supervisor reads the copy of the last
//! answer it received from that worker. The supervisor never sends a worker a command of the
//! same parity as that answer (see [`super::command::next_seq`]), so a worker killed half-way through its
//! books leaves the copy the supervisor reads whole. Entries are atomic words: a torn write is
//! impossible on any platform.

use std::sync::atomic::{AtomicU64, Ordering};

use rogue_gym_ipc::{IpcError, SharedBuffer};

/// Name of the pool's books buffer (`/dev/shm/<pool>books`).
pub(crate) const BOOKS_BUFFER: &str = "books";

/// Words per env and copy: the episode index, the episode's seed.
const WORDS: usize = 2;

/// Bytes of the books of `num_envs` envs.
pub(crate) fn books_bytes(num_envs: usize) -> usize {
    2 * num_envs * WORDS * 8
}

/// Episode indices count a worker's episodes one by one from 0: none reaches this (at a
/// billion episodes a second, it takes 146 years). A larger one in the books was not written
/// by a working worker.
pub(crate) const MAX_EPISODE: u64 = 1 << 62;

/// The index of the episode after episode `e` as the books hold it, or `None` when `e` is no
/// episode index (above [`MAX_EPISODE`]).
pub(crate) fn next_episode(e: u64) -> Option<u64> {
    (e < MAX_EPISODE).then(|| e + 1)
}

// A next episode is never the partial reset's "keep this env's episode".
const _: () = assert!(MAX_EPISODE < super::KEEP_EPISODE);

/// The books of a pool, mapped.
#[derive(Debug)]
pub(crate) struct Books {
    buf: SharedBuffer,
    num_envs: usize,
}

impl Books {
    /// Create them (supervisor; zero-filled, sealed: [`SharedBuffer::create`]).
    pub(crate) fn create(num_envs: usize) -> Result<Self, IpcError> {
        let buf = SharedBuffer::create(BOOKS_BUFFER, books_bytes(num_envs))?;
        Ok(Books { buf, num_envs })
    }

    /// Map them from the descriptor the supervisor handed down (worker).
    pub(crate) fn from_fd(fd: std::os::fd::OwnedFd, num_envs: usize) -> Result<Self, IpcError> {
        let buf = SharedBuffer::from_fd(fd, BOOKS_BUFFER, books_bytes(num_envs))?;
        Ok(Books { buf, num_envs })
    }

    /// The buffer (its descriptor, for the workers).
    pub(crate) fn buffer(&self) -> &SharedBuffer {
        &self.buf
    }

    fn word(&self, seq: u64, env: usize, w: usize) -> &AtomicU64 {
        assert!(env < self.num_envs);
        let copy = (seq % 2) as usize;
        // SAFETY: the mapping holds `2 * num_envs * WORDS` u64 words, 8-aligned (mmap is
        // page-aligned), and lives as long as `self`; every access is atomic.
        unsafe {
            &*(self.buf.as_ptr() as *const AtomicU64).add((copy * self.num_envs + env) * WORDS + w)
        }
    }

    /// (worker) Env `env`'s episode index and seed, in the copy of command `seq`.
    pub(crate) fn write(&self, seq: u64, env: usize, episode: u64, seed: u64) {
        self.word(seq, env, 0).store(episode, Ordering::Relaxed);
        self.word(seq, env, 1).store(seed, Ordering::Relaxed);
    }

    /// (supervisor) Env `env`'s episode index and seed as of answer `seq`. The answer's
    /// arrival (an acquire in the transport) orders these reads after the worker's writes.
    pub(crate) fn read(&self, seq: u64, env: usize) -> (u64, u64) {
        (
            self.word(seq, env, 0).load(Ordering::Relaxed),
            self.word(seq, env, 1).load(Ordering::Relaxed),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::{MAX_EPISODE, next_episode};
    use crate::wire::command::next_seq;

    #[test]
    fn no_value_in_the_books_makes_a_next_episode_that_wraps_or_keeps() {
        assert_eq!(next_episode(0), Some(1));
        assert_eq!(next_episode(MAX_EPISODE - 1), Some(MAX_EPISODE));
        for e in [MAX_EPISODE, u64::MAX - 1, u64::MAX] {
            assert_eq!(next_episode(e), None);
        }
    }

    #[test]
    fn the_next_command_never_writes_the_copy_being_read() {
        assert_eq!(next_seq(0, None), 1);
        for seq in 0..10u64 {
            for d in 0..=seq {
                assert_ne!(next_seq(seq, Some(d)) % 2, d % 2);
                assert!(next_seq(seq, Some(d)) > seq);
            }
        }
    }
}

/// The handshake of a whole-batch call, model-checked with loom (every interleaving and every
/// memory ordering the C11 model allows, as weak as ARM's): a worker writes its envs' rows in
/// place (plain memory) and its books copy, then publishes its answer (the transport's
/// publish: a release; its receive: an acquire); the supervisor reads rows and books once the
/// answer is in, and reads the books of the last answer while a restarted worker writes the
/// next command's. The same model with a relaxed publish, or with commands numbered one by one
/// (no parity skip), fails: the checks can fail.
#[cfg(all(test, feature = "loom"))]
mod loom_model {
    use loom::cell::UnsafeCell;
    use loom::sync::Arc;
    use loom::sync::atomic::{AtomicU64, Ordering};

    const ENVS: usize = 2;

    /// What the worker and the supervisor share: the rows of a slot, the two books copies,
    /// and the transport (the last command sent, the last answer published).
    struct Shm {
        rows: [UnsafeCell<u64>; ENVS],
        books: [[AtomicU64; ENVS]; 2],
        command: AtomicU64,
        answer: AtomicU64,
    }

    /// Env `e`'s value after command `seq`.
    fn value(seq: u64, e: usize) -> u64 {
        seq * 10 + e as u64
    }

    /// A worker serving command `seq`: rows, then books, then the answer; `killed` stops it
    /// after the first env's books (no answer).
    fn serve(shm: &Shm, seq: u64, publish: Ordering, killed: bool) {
        while shm.command.load(Ordering::Acquire) != seq {
            loom::thread::yield_now();
        }
        for e in 0..ENVS {
            // SAFETY (of the model): the supervisor reads rows only after the answer.
            shm.rows[e].with_mut(|r| unsafe { *r = value(seq, e) });
        }
        for e in 0..ENVS {
            shm.books[(seq % 2) as usize][e].store(value(seq, e), Ordering::Relaxed);
            if killed {
                return;
            }
        }
        shm.answer.store(seq, publish);
    }

    fn wait_answer(shm: &Shm, seq: u64) {
        while shm.answer.load(Ordering::Acquire) != seq {
            loom::thread::yield_now();
        }
    }

    fn run(next: fn(u64, Option<u64>) -> u64, publish: Ordering) {
        loom::model(move || {
            let shm = Arc::new(Shm {
                rows: std::array::from_fn(|_| UnsafeCell::new(0)),
                books: std::array::from_fn(|_| std::array::from_fn(|_| AtomicU64::new(0))),
                command: AtomicU64::new(0),
                answer: AtomicU64::new(0),
            });
            // A command answered; the next one's worker killed half-way through its books.
            let first = next(0, None);
            let second = next(first, Some(first));
            let w = shm.clone();
            let worker = loom::thread::spawn(move || {
                serve(&w, first, publish, false);
                serve(&w, second, publish, true);
            });
            shm.command.store(first, Ordering::Release);
            wait_answer(&shm, first);
            for e in 0..ENVS {
                // SAFETY (of the model): the worker wrote the rows before its answer.
                let row = shm.rows[e].with(|r| unsafe { *r });
                assert_eq!(row, value(first, e), "a row of the answer");
                let book = shm.books[(first % 2) as usize][e].load(Ordering::Relaxed);
                assert_eq!(book, value(first, e), "the books of the answer");
            }
            shm.command.store(second, Ordering::Release);
            worker.join().unwrap();
            // Its successor serves the next command while the supervisor reads the books of
            // the last answer (a reset's episodes, a failure report).
            let third = next(second, Some(first));
            let w = shm.clone();
            let successor = loom::thread::spawn(move || serve(&w, third, publish, false));
            shm.command.store(third, Ordering::Release);
            for e in 0..ENVS {
                let book = shm.books[(first % 2) as usize][e].load(Ordering::Relaxed);
                assert_eq!(book, value(first, e), "the books being read stay whole");
            }
            wait_answer(&shm, third);
            for e in 0..ENVS {
                // SAFETY (of the model): as above.
                let row = shm.rows[e].with(|r| unsafe { *r });
                assert_eq!(row, value(third, e), "a row of the successor's answer");
            }
            successor.join().unwrap();
        });
    }

    #[test]
    fn loom_the_handshake_holds_in_every_interleaving() {
        run(crate::wire::command::next_seq, Ordering::Release);
    }

    #[test]
    #[should_panic(expected = "Causality violation")]
    fn loom_a_relaxed_publish_is_caught() {
        run(crate::wire::command::next_seq, Ordering::Relaxed);
    }

    #[test]
    #[should_panic(expected = "the books being read stay whole")]
    fn loom_commands_numbered_one_by_one_are_caught() {
        run(|seq, _| seq + 1, Ordering::Release);
    }
}
