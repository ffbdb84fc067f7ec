//! What a worker writes back, whichever executor served the command: the batch slot a
//! command names ([`Worker::slot_rows`]), the extra info that did not fit its rooms (the one
//! side-file writer, [`Worker::write_apart`]) and its answers (the one publisher,
//! [`Worker::publish_answer`]), each an iceoryx2 sample of answer words and, for a partial
//! answer, its rows.

use rogue_gym_ipc::BlockHeader;

use super::{Worker, WorkerError};
use crate::stats::{Counter, ns_since, stamp};
use crate::wire::answer::{ANSWER_WORDS, Answer, BlockKind, sample_words};
use crate::wire::slot_layout::SlotRows;
use crate::wire::{EnvFault, calls, extra_apart_path};

impl Worker<'_> {
    /// The rows of batch slot `target - 1` (`target` checked: 1 to `batch_slots`).
    pub(super) fn slot_rows(&self, target: u64) -> SlotRows {
        // SAFETY: `target <= batch_slots` (every command's slots are checked,
        // `check_command`): inside the batch buffer, 64-byte aligned.
        unsafe {
            let base = self
                .batch
                .as_ptr()
                .add((target as usize - 1) * self.slot_layout.bytes());
            self.slot_layout.rows(base)
        }
    }

    /// Write the extra info that did not fit its rooms (`(row, bytes)`) beside answer `n`, in
    /// a private file named by it; the supervisor takes it with the answer.
    pub(super) fn write_apart(&self, n: u64, apart: &[(u32, Vec<u8>)]) -> Result<(), String> {
        let entries: Vec<(u32, &[u8])> = apart.iter().map(|(j, b)| (*j, b.as_slice())).collect();
        let path = extra_apart_path(&self.id, self.args.index, self.args.generation, n);
        calls::write(&path, &calls::encode(&entries))
    }

    /// [`Worker::write_apart`] for a command's answer: a failure is its first env's fault.
    pub(super) fn write_apart_of(&self, n: u64, apart: &[(u32, Vec<u8>)]) -> Result<(), EnvFault> {
        match apart.first() {
            None => Ok(()),
            Some((j, _)) => self.write_apart(n, apart).map_err(|e| {
                EnvFault::new(
                    (self.first_env as u64) + u64::from(*j),
                    "extra info",
                    format!("cannot write the info that did not fit its room: {e}"),
                )
            }),
        }
    }

    /// Publish answer `n` of kind `kind`: `answer`'s words (none: a zero word, naming no
    /// rows) and, for a partial answer, the rows of the block it is for.
    pub(super) fn publish_answer(
        &mut self,
        n: u64,
        kind: BlockKind,
        answer: Option<&Answer>,
        rows: &[u64],
    ) -> Result<(), WorkerError> {
        let mut block = self.ports.loan_block(sample_words(self.block_envs))?;
        *block.user_header_mut() = self.header(n, kind);
        let p = block.payload_mut();
        let at = match answer {
            Some(a) => {
                p[..ANSWER_WORDS].copy_from_slice(&a.encode());
                ANSWER_WORDS
            }
            None => 0,
        };
        if rows.is_empty() {
            if answer.is_none() {
                p[0] = 0;
            }
        } else {
            p[at] = rows.len() as u64;
            p[at + 1..at + 1 + rows.len()].copy_from_slice(rows);
        }
        let t = stamp();
        self.ports.send_block(block)?;
        self.answers += 1;
        self.stats
            .add(self.args.index, Counter::PublishNs, ns_since(t));
        Ok(())
    }

    /// Send an answer without data (`kind`) to command `seq`.
    pub(super) fn send(&mut self, seq: u64, kind: BlockKind) -> Result<(), WorkerError> {
        self.publish_answer(seq, kind, None, &[])
    }

    fn header(&self, seq: u64, kind: BlockKind) -> BlockHeader {
        BlockHeader {
            seq,
            generation: self.args.generation,
            worker: self.args.index as u32,
            kind: kind.word(),
            ready_ns: 0,
        }
    }

    /// Report env fault `f` as the answer to command `seq` (the supervisor raises it to the
    /// caller and requires a reset); the worker itself is fine and serves on.
    pub(super) fn report(&mut self, seq: u64, f: &EnvFault) -> Result<(), WorkerError> {
        f.write(&self.fault_path).map_err(WorkerError::Msg)?;
        self.send(seq, BlockKind::Error)
    }
}
