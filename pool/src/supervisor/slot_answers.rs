//! The answers of a whole-batch call (step, reset, partial reset): the workers wrote every
//! row in place in the call's batch slot, so the supervisor takes one answer per worker, as
//! the answers arrive, checked by the intake (`intake.rs`), and folds them into the call's
//! [`SlotAnswer`].

use super::Supervisor;
use super::intake::{Apart, Runs, slot_extra};
use crate::batch::{SlotAnswer, SlotExtras};
use crate::error::PoolError;
use crate::wire::answer::{AnswerExtras, EXTRA_HEAD};
use crate::wire::slot_layout::SlotRows;

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
        while let Some(k) = self.arrived.pop_front() {
            let slot = acc.answer.slot;
            let at = |c: &Self, _, out: &mut Runs| out.push((c.blocks[k].clone(), slot));
            let Some(t) = self.take_checked(k, at)? else {
                continue;
            };
            if t.recycled {
                self.recycling.replaced_envs.extend(self.blocks[k].clone());
            }
            acc.ready_ns = acc.ready_ns.max(t.ready_ns);
            acc.answered += 1;
            if t.restart {
                // Its envs report the restart, not their reset's final obs or info.
                acc.answer.restarted = true;
                acc.restarted.push(k);
                acc.not_uniform = true;
                continue;
            }
            acc.answer.final_obs |= t.answer.final_obs;
            acc.apart.extend(t.apart);
            match t.answer.extras {
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

    /// The extra info of a whole-batch call, once every worker answered.
    fn slot_extras(&self, acc: &mut SlotCollect, rows: &SlotRows) -> SlotExtras {
        match (acc.mixed.is_empty(), acc.not_uniform, acc.uniform) {
            (true, _, _) if acc.apart.is_empty() => SlotExtras::None,
            (false, false, Some((size, _))) => SlotExtras::Uniform(size),
            _ => {
                // Not one layout (e.g. infos that are pickled): env by env, each as long as
                // its `extra_len` says, at most its room (the async API's joiner).
                let mut out = std::mem::take(&mut acc.apart);
                for &k in &acc.mixed {
                    for i in self.blocks[k].clone() {
                        out.extend(slot_extra(rows, i, &rows.read(i), None).map(|x| (i, x)));
                    }
                }
                out.sort_by_key(|(i, _)| *i);
                SlotExtras::Rows(out)
            }
        }
    }
}
