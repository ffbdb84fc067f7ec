//! The answers of a whole-batch call (step, reset, partial reset): the workers wrote every
//! row in place in the call's batch slot, so the supervisor takes one answer per worker, as
//! the answers arrive, checked by the intake (`intake.rs`), and folds them into the call's
//! [`SlotAnswer`].

use super::Supervisor;
use super::intake::Apart;
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
            let arrived = self.take_answer(k)?;
            let s = &mut self.workers[k];
            let restarted = std::mem::take(&mut s.restarted);
            if std::mem::take(&mut s.recycled) && restarted {
                self.recycling.replaced_envs.extend(self.blocks[k].clone());
            }
            acc.ready_ns = acc.ready_ns.max(arrived.ready_ns);
            let at = [(self.blocks[k].clone(), acc.answer.slot)];
            let Some((answer, apart)) = self.checked(k, &arrived, &at)? else {
                continue;
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
