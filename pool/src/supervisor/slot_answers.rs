//! The answers of a whole-batch call (step, reset, partial reset): the workers wrote every
//! row in place in the call's batch slot, so the supervisor takes one answer per worker, as
//! the answers arrive, and checks what each says before it believes it ([`Answer::decode`],
//! the flag bytes of its rows, the rows of its side file). A worker whose answer fails a check
//! is handled as a failed worker ([`FailureCause::Corrupt`]).

use rogue_gym_ipc::BlockSample;

use super::Supervisor;
use super::workers::LinkState;
use crate::batch::{SlotAnswer, SlotExtras};
use crate::error::{FailureCause, PoolError};
use crate::wire::answer::{ANSWER_WORDS, Answer, AnswerExtras, EXTRA_HEAD};
use crate::wire::slot_layout::SlotRows;
use crate::wire::{calls, extra_apart_path};

/// Extra info that travelled beside an answer (it did not fit its env's room), as
/// `(env, bytes)`.
pub(super) type Apart = Vec<(usize, Vec<u8>)>;

/// A whole-batch call's answers, taken worker by worker as they arrive.
#[derive(Debug, Default)]
pub(super) struct SlotCollect {
    /// What the call answers so far.
    pub(super) answer: SlotAnswer,
    /// Workers whose answer was taken.
    pub(super) answered: usize,
    /// When the last answer so far was published (the workers' stamp, `CLOCK_MONOTONIC`).
    pub(super) ready_ns: u64,
    /// Workers whose envs wrote extra info not of one layout.
    mixed: Vec<usize>,
    /// Workers restarted during the call (their envs report it).
    restarted: Vec<usize>,
    /// Extra info that travelled beside the answers.
    apart: Apart,
    /// The layout of every answer's extra info so far, while all are one.
    uniform: Option<(usize, [u8; EXTRA_HEAD])>,
    not_uniform: bool,
}

impl SlotCollect {
    /// The collection of a call into slot `slot`.
    pub(super) fn new(slot: usize) -> Self {
        SlotCollect {
            answer: SlotAnswer {
                slot,
                ..Default::default()
            },
            ..Default::default()
        }
    }
}

impl Supervisor {
    /// Take the answers that have arrived for the whole-batch call into slot
    /// `acc.answer.slot`, as they come (a worker whose answer is taken is idle again: if it
    /// dies now, it is replaced at once). The one case the supervisor writes rows: a restarted
    /// worker's envs are marked restarted (their episodes were cut).
    pub(super) fn take_slot_answers(&mut self, acc: &mut SlotCollect) -> Result<(), PoolError> {
        if self.arrived.is_empty() {
            return Ok(()); // nothing new: the usual poll while the workers step
        }
        let rows = self.rows_of(acc.answer.slot)?;
        let room = self.slot_layout.extra_bytes;
        while let Some(k) = self.arrived.pop_front() {
            let sample = self.take_answer(k)?;
            let s = &mut self.workers[k];
            let restarted = std::mem::take(&mut s.restarted);
            if std::mem::take(&mut s.recycled) && restarted {
                self.recycling.replaced_envs.extend(self.blocks[k].clone());
            }
            let (words, seq) = answer_words(&sample);
            acc.ready_ns = acc.ready_ns.max(sample.user_header().ready_ns);
            drop(sample);
            let checked = Answer::decode(&words, room).and_then(|a| {
                self.check_flags(&rows, self.blocks[k].clone())?;
                Ok(a)
            });
            let answer = match checked {
                Ok(a) => a,
                Err(what) => {
                    self.lose_corrupt(k, format!("its answer to command {seq}: {what}"))?;
                    continue;
                }
            };
            let apart = if answer.apart {
                match self.take_apart(k, seq) {
                    Ok(apart) => apart,
                    Err(what) => {
                        self.lose_corrupt(k, what)?;
                        continue;
                    }
                }
            } else {
                Vec::new()
            };
            acc.answered += 1;
            if restarted {
                // Its envs report the restart, not their reset's final obs or info.
                acc.answer.restarted = true;
                acc.restarted.push(k);
                acc.not_uniform = true;
                for i in self.blocks[k].clone() {
                    rows.mark_restarted(i);
                }
                continue;
            }
            acc.answer.final_obs |= answer.final_obs;
            acc.apart.extend(apart);
            match answer.extras {
                AnswerExtras::None => acc.not_uniform = true,
                AnswerExtras::Mixed => {
                    acc.not_uniform = true;
                    acc.mixed.push(k);
                }
                AnswerExtras::Uniform { size, head } => {
                    acc.not_uniform |= acc.uniform.is_some_and(|u| u != (size, head));
                    acc.uniform = Some((size, head));
                    acc.mixed.push(k);
                }
            }
        }
        if acc.answered == self.workers.len() {
            acc.answer.extras = self.slot_extras(acc, &rows);
            if acc.answer.restarted {
                // No worker writes `restarted` (its envs cannot know): the column is the
                // supervisor's, written whole here.
                for (k, b) in self.blocks.iter().enumerate() {
                    if !acc.restarted.contains(&k) {
                        b.clone().for_each(|i| rows.clear_restarted(i));
                    }
                }
            }
        }
        Ok(())
    }

    /// Check the flag bytes a worker wrote in rows `envs` of a slot: those handed out as
    /// `bool` (`terminated`, `truncated`, the env's flag infos) and, in SAME_STEP mode,
    /// `has_final_obs`, which says which final observations to read.
    pub(super) fn check_flags(
        &self,
        rows: &SlotRows,
        envs: std::ops::Range<usize>,
    ) -> Result<(), String> {
        for &f in &self.flags {
            rows.check_flags(f, envs.clone())?;
        }
        Ok(())
    }

    /// Worker `k`'s answer, which has arrived (it is idle again).
    pub(super) fn take_answer(&mut self, k: usize) -> Result<BlockSample, PoolError> {
        let s = &mut self.workers[k];
        match std::mem::replace(&mut s.state, LinkState::Idle) {
            LinkState::Ready(sample) => Ok(sample),
            other => {
                s.state = other;
                Err(PoolError::State(format!("worker {k} has no answer ready")))
            }
        }
    }

    /// The extra info that did not fit its envs' rooms and travelled beside worker `k`'s
    /// answer `seq`, as `(env, bytes)`: the one reader of that side file. Each entry's row
    /// must be one of the worker's envs, once; an error says what was wrong.
    pub(super) fn take_apart(&mut self, k: usize, seq: u64) -> Result<Apart, String> {
        let path = extra_apart_path(&self.id, k, self.workers[k].generation, seq);
        let entries = calls::take(&path)
            .map_err(|e| format!("the extra info beside its answer {seq}: {e}"))?;
        let block = self.blocks[k].clone();
        let mut seen = vec![false; block.len()];
        for (j, _) in &entries {
            match seen.get_mut(*j as usize) {
                Some(s) if !*s => *s = true,
                Some(_) => {
                    return Err(format!(
                        "the extra info of row {j} twice beside answer {seq}"
                    ));
                }
                None => {
                    return Err(format!(
                        "extra info for row {j} beside answer {seq}, but it hosts {} envs",
                        block.len()
                    ));
                }
            }
        }
        self.counts[k].spilled_bytes += entries.iter().map(|(_, b)| b.len() as u64).sum::<u64>();
        Ok(entries
            .into_iter()
            .map(|(j, b)| (block.start + j as usize, b))
            .collect())
    }

    /// Worker `k` answered with values outside their bounds (`what` says which): it is
    /// handled as a failed worker (killed, then restarted or raised per the failure policy),
    /// and its envs' episodes were cut.
    pub(super) fn lose_corrupt(&mut self, k: usize, what: String) -> Result<(), PoolError> {
        self.lose(k, FailureCause::Corrupt(what), true)
    }

    /// The extra info of a whole-batch call, once every worker answered.
    fn slot_extras(&self, acc: &mut SlotCollect, rows: &SlotRows) -> SlotExtras {
        match (acc.mixed.is_empty(), acc.not_uniform, acc.uniform) {
            (true, _, _) if acc.apart.is_empty() => SlotExtras::None,
            (false, false, Some((size, _))) => SlotExtras::Uniform(size),
            _ => {
                // Not one layout (e.g. infos that are pickled): env by env, each as long as
                // its `extra_len` says, at most its room.
                let xb = self.slot_layout.extra_bytes;
                // SAFETY: every worker has answered: no one writes the slot now.
                let room = unsafe { rows.extra_rows(0..self.slot_layout.num_envs) };
                let mut out = std::mem::take(&mut acc.apart);
                for &k in &acc.mixed {
                    for i in self.blocks[k].clone() {
                        let len = (rows.read(i).extra_len as usize).min(xb);
                        if len > 0 {
                            out.push((i, room[i * xb..i * xb + len].to_vec()));
                        }
                    }
                }
                out.sort_by_key(|(i, _)| *i);
                SlotExtras::Rows(out)
            }
        }
    }
}

/// An answer's first words and its command's sequence number (zeros where a block is too
/// short to hold them: [`Answer::decode`] refuses those).
pub(super) fn answer_words(sample: &BlockSample) -> ([u64; ANSWER_WORDS], u64) {
    let mut words = [0u64; ANSWER_WORDS];
    if let Some(w) = sample.payload().get(..ANSWER_WORDS) {
        words.copy_from_slice(w);
    }
    (words, sample.user_header().seq)
}
