//! A reset or step served inline: on the worker's own thread, env after env (or the block's
//! vector env at once), each env writing its rows in place in the slot the command names for
//! it (`block_out.rs`), streamed for large batches (`streaming.rs`).

use super::block_out::BlockOut;
use super::env_state::ServeCtx;
use super::executor::{Named, Slots};
use super::{Worker, WorkerError, streaming};
use crate::stats::{Counter, ns_since, stamp};
use crate::wire::answer::{AnswerBuilder, BlockKind};
use crate::wire::{EnvFault, Serve};

impl Worker<'_> {
    /// A checked reset or step ([`Serve`]) served on the worker's own thread: every env it
    /// names (or the block's vector env) writes its rows in the batch slot the command names
    /// for it, slot by slot; their books written, the extra info apart beside the answer, one
    /// answer for them all (or the env fault's: `extras`, the failure of its action extras).
    pub(super) fn serve_inline(
        &mut self,
        seq: u64,
        kind: Serve,
        named: &Named<'_>,
        extras: Result<(), EnvFault>,
    ) -> Result<(), WorkerError> {
        let (me, epw) = (self.args.index, self.block_envs);
        self.served += 1;
        let misdeed = self.misdeed(self.served);
        let serving = stamp();
        let ctx = ServeCtx {
            seeds: &self.seeds,
            num_envs: self.cfg.num_envs as u64,
            autoreset: self.cfg.autoreset,
            action_bytes: self.action_bytes,
            n_info: self.n_info,
        };
        // One pass per slot the command writes (a whole command writes one).
        let mut built = AnswerBuilder::default();
        let mut apart: Vec<(u32, Vec<u8>)> = Vec::new();
        let mut served = extras.map(|()| 0);
        for slot in named.slots.written(self.cfg.batch_slots as u64) {
            let only = match named.slots {
                Slots::All(_) => None,
                Slots::Each(t) => Some((t, slot)),
            };
            let rows = self.slot_rows(slot);
            // SAFETY: this worker's envs own their rows of the slot during the command: the
            // supervisor neither reads nor lends them out until the command is answered, and
            // no other worker writes them.
            let mut out =
                unsafe { BlockOut::in_slot(rows, self.first_env, epw, &mut self.scratch) };
            out.answer = built;
            served = served.and_then(|c| {
                let w = named.words;
                let more = self
                    .envs
                    .serve(kind, w, named.per_env, only, &mut out, &ctx)?;
                Ok(c + more)
            });
            built = out.answer;
            apart.extend(out.take_apart());
            if served.is_err() {
                break;
            }
        }
        if self.streamed {
            // Streamed rows land before the answer that publishes them (an env that failed
            // midway included: its rows are written again before anyone reads them).
            streaming::fence();
        }
        let mut answer = built.finish(epw);
        let served = served.and_then(|s| self.write_apart_of(seq, &apart).map(|()| s));
        self.stats.add(me, Counter::EnvNs, ns_since(serving));
        self.stats.add(me, Counter::Commands, 1);
        if served.is_ok() {
            self.envs.write_books(&self.books, seq, self.first_env);
        }
        if let (Some(m), Ok(_)) = (&misdeed, &served) {
            // At the first env the command served, in its slot.
            let j = (0..epw).find(|&j| named.slots.of(j) != 0).unwrap_or(0);
            self.commit(m, seq, (named.slots.of(j) as usize, j), &mut answer);
        }
        match served {
            Ok(served) => {
                self.stats.add(me, Counter::EnvSteps, served as u64);
                self.publish_answer(seq, BlockKind::Data, Some(&answer), &[])
            }
            Err(f) => self.report(seq, &f),
        }
    }
}
