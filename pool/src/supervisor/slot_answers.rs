//! The answers of a whole-batch call (step, reset, partial reset): the workers wrote every
//! row in place in the call's batch slot, so the supervisor takes one answer word per worker,
//! as the answers arrive, and waits for them as long as they usually take.

use std::time::{Duration, Instant};

use rogue_gym_ipc::BlockSample;

use super::Supervisor;
use super::workers::LinkState;
use crate::batch::{SlotAnswer, SlotExtras};
use crate::error::PoolError;
use crate::wire::slot_layout::{RowWriter, SlotLayout};
use crate::wire::{
    SLOT_ANSWER_WORDS, SLOT_EXTRA_ANY, SLOT_EXTRA_APART, SLOT_EXTRA_UNIFORM, SLOT_FINAL, calls,
    extra_apart_path,
};

/// A whole-batch call's answers, taken worker by worker as they arrive.
#[derive(Debug, Default)]
pub(super) struct SlotCollect {
    /// What the call answers so far.
    pub(super) answer: SlotAnswer,
    /// Workers whose answer was taken.
    pub(super) answered: usize,
    /// When the last answer so far was published (the workers' stamp, `CLOCK_MONOTONIC`).
    pub(super) ready_ns: u64,
    /// Workers whose envs wrote extra info.
    irregular: Vec<usize>,
    /// Extra info that travelled beside the answers.
    apart: Vec<(usize, Vec<u8>)>,
    /// Each answer's extra layout (size, head), while all agree.
    uniform: Option<[u64; 3]>,
    all_uniform: bool,
}

impl SlotCollect {
    /// The collection of a call into slot `slot`.
    pub(super) fn new(slot: usize) -> Self {
        SlotCollect {
            answer: SlotAnswer {
                slot,
                ..Default::default()
            },
            all_uniform: true,
            ..Default::default()
        }
    }
}

/// Calls shorter than this are polled for from start to end (when the caller has a core of
/// its own); longer ones are slept through for three quarters first.
const FULL_POLL: Duration = Duration::from_millis(20);

impl Supervisor {
    /// Take the answers that have arrived for the whole-batch call into slot `acc.slot`, as
    /// they come (a worker whose answer is taken is idle again: if it dies now, it is
    /// replaced at once). The workers wrote every row in place; one word per worker says what
    /// else there is to read. The one case the supervisor writes rows: a restarted worker's
    /// envs are marked restarted (their episodes were cut).
    pub(super) fn take_slot_answers(&mut self, acc: &mut SlotCollect) -> Result<(), PoolError> {
        if self.async_api.ready_order.is_empty() && acc.answered < self.workers.len() {
            return Ok(()); // nothing new: the usual poll while the workers step
        }
        let layout = self.slot_layout;
        let writer = self.writer_of(acc.answer.slot)?;
        while let Some(k) = self.async_api.ready_order.pop_front() {
            let sample = self.take_answer(k)?;
            let s = &mut self.workers[k];
            acc.answered += 1;
            let restarted = std::mem::take(&mut s.restarted);
            let block = self.blocks[k].clone();
            if std::mem::take(&mut s.recycled) && restarted {
                self.recycling.replaced_envs.extend(block.clone());
            }
            let mut words = [0u64; SLOT_ANSWER_WORDS];
            words.copy_from_slice(&sample.payload()[..SLOT_ANSWER_WORDS]);
            let (bits, seq) = (words[0], sample.user_header().seq);
            acc.ready_ns = acc.ready_ns.max(sample.user_header().ready_ns);
            drop(sample);
            if restarted {
                acc.answer.restarted = true;
                for i in block.clone() {
                    writer.mark_restarted(i);
                }
            } else if bits & SLOT_FINAL != 0 {
                acc.answer.final_obs = true;
            }
            if bits & SLOT_EXTRA_APART != 0 {
                let apart = self.take_apart(k, seq)?;
                if !restarted {
                    acc.apart.extend(apart);
                }
            }
            if bits & SLOT_EXTRA_ANY == 0 || restarted {
                // Not every env wrote extra info (a restarted worker's envs report the restart,
                // not their reset's info).
                acc.all_uniform = false;
                continue;
            }
            acc.irregular.push(k);
            let key = [words[1], words[2], words[3]];
            if bits & SLOT_EXTRA_UNIFORM == 0 || acc.uniform.is_some_and(|u| u != key) {
                acc.all_uniform = false;
            }
            acc.uniform = Some(key);
        }
        if acc.answered == self.workers.len() {
            acc.answer.extras = self.slot_extras(acc, &writer, &layout);
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
    /// answer `seq` written in place, as `(env, bytes)`.
    pub(super) fn take_apart(
        &mut self,
        k: usize,
        seq: u64,
    ) -> Result<Vec<(usize, Vec<u8>)>, PoolError> {
        let path = extra_apart_path(&self.id, k, self.workers[k].generation, seq);
        let entries = calls::take(&path).map_err(|e| {
            PoolError::Io(format!(
                "worker {k}: the extra info beside answer {seq}: {e}"
            ))
        })?;
        self.counts[k].spilled_bytes += entries.iter().map(|(_, b)| b.len() as u64).sum::<u64>();
        let first = self.blocks[k].start;
        Ok(entries
            .into_iter()
            .map(|(j, b)| (first + j as usize, b))
            .collect())
    }

    /// The extra info of a whole-batch call, once every worker answered.
    fn slot_extras(
        &self,
        acc: &mut SlotCollect,
        writer: &RowWriter,
        layout: &SlotLayout,
    ) -> SlotExtras {
        match (acc.irregular.is_empty(), acc.all_uniform, acc.uniform) {
            (true, _, _) if acc.apart.is_empty() => SlotExtras::None,
            (false, true, Some([size, _, _])) => SlotExtras::Uniform(size as usize),
            _ => {
                // Not one layout (e.g. infos that are pickled): env by env.
                let xb = layout.extra_bytes;
                // SAFETY: every worker has answered: no one writes the slot now.
                let room = unsafe { writer.extra_rows(0..layout.num_envs) };
                let mut rows = std::mem::take(&mut acc.apart);
                for &k in &acc.irregular {
                    for i in self.blocks[k].clone() {
                        let len = (writer.read(i).extra_len as usize).min(xb);
                        if len > 0 {
                            rows.push((i, room[i * xb..i * xb + len].to_vec()));
                        }
                    }
                }
                rows.sort_by_key(|(i, _)| *i);
                SlotExtras::Rows(rows)
            }
        }
    }

    /// A writer of slot `slot`'s rows.
    pub(super) fn writer_of(&self, slot: usize) -> Result<RowWriter, PoolError> {
        match &self.batch {
            // SAFETY: the slot lies inside the mapping, which `self.batch` keeps alive; it is
            // 64-byte aligned (page-aligned mapping, 64-byte slots).
            Some(b) if slot < self.cfg.batch_slots => unsafe {
                Ok(self
                    .slot_layout
                    .writer(b.as_ptr().add(slot * self.slot_layout.bytes())))
            },
            _ => Err(PoolError::Closed),
        }
    }

    /// How to wait for the answers of the whole-batch call in flight, when the workers leave
    /// the caller a core (fewer workers than cores) and the last call took at most 50 ms: poll
    /// through a call of under [`FULL_POLL`] (for up to twice its time); for a longer one, sleep until three quarters of it
    /// have passed since the call was sent (less 200 us: the CPU is free meanwhile, and an
    /// early answer still wakes it), then poll for up to half of it (at most 2 ms), so that the
    /// answer is seen without a wake-up. `None`: the pool's own policy.
    pub(super) fn expected_wait(&self) -> Option<rogue_gym_ipc::WaitPolicy> {
        let expected = self.call.expected_answer?;
        if self.workers.len() >= self.cores || expected > Duration::from_millis(50) {
            return None;
        }
        if expected < FULL_POLL {
            // Poll through a short call: a sleep shorter than the kernel's timer slack (50 us)
            // would only oversleep, and a wake-up costs tens of microseconds.
            return Some(rogue_gym_ipc::WaitPolicy {
                poll_budget: self.cfg.wait.poll_budget.max(expected * 2),
                ..self.cfg.wait
            });
        }
        let wake = self.call.split_sent + expected * 3 / 4 - Duration::from_micros(200);
        Some(rogue_gym_ipc::WaitPolicy {
            sleep_first: wake.saturating_duration_since(Instant::now()),
            poll_budget: self
                .cfg
                .wait
                .poll_budget
                .max((expected / 2).min(Duration::from_millis(2))),
            ..self.cfg.wait
        })
    }
}
