//! A bad value one worker writes on purpose: the test hook of the caller's checks
//! ([`crate::PoolConfig::sabotage`]). Nothing but the pool's own tests sets it; a worker
//! without it runs no code of `worker/sabotage.rs`.

use serde::{Deserialize, Serialize};

/// One worker's misdeed, once: worker `worker` commits it while it serves its `at`-th reset
/// or step command (1: the first, the reset after its start).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Sabotage {
    /// The worker that misbehaves.
    pub worker: usize,
    /// Which of its reset or step commands (1: the first).
    pub at: u64,
    /// What it does.
    pub what: Misdeed,
}

/// What a sabotaging worker does, in the answer of its command.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Misdeed {
    /// the answer says every env wrote `size` bytes of extra info.
    ExtraSize {
        /// The size said.
        size: u64,
    },
    /// extra info travels beside the answer for row `row` of its block.
    ApartRow {
        /// The row, counted from the block's first env.
        row: u32,
    },
    /// Its envs' episode books say episode `episode`.
    Episode {
        /// The episode index written.
        episode: u64,
    },
    /// its first env's `terminated` byte is `byte`.
    FlagByte {
        /// The byte written.
        byte: u8,
    },
    /// its first env's extra info is `bytes` (at most its room).
    InfoBytes {
        /// The bytes written.
        bytes: Vec<u8>,
    },
    /// It tries to resize the pool's batch buffer, as any process of the user could (through
    /// the supervisor's descriptor in `/proc`), and says on its stderr what happened.
    Truncate,
    /// It is killed (SIGKILL) after writing its rows and half of its books, before its answer.
    DieMidWrite,
}
