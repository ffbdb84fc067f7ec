//! The supervisor's one intake: every answer of every worker arrives here
//! ([`Supervisor::poll_all`]), and every answer that says its envs' rows are written is
//! decoded and checked here, once, before anyone reads a row ([`Supervisor::checked`]: its
//! words, the flag bytes of the rows it names, the extra info beside it). A worker whose
//! answer fails a check is handled as a failed worker ([`FailureCause::Corrupt`]). A checked
//! answer ([`Supervisor::take_checked`]) becomes ready runs of the one lane (`async_api.rs`,
//! `async_envs/`), whichever API sent it.

use std::ops::Range;

use rogue_gym_ipc::BlockSample;

use super::Supervisor;
use super::link::{Arrived, LinkState};
use crate::error::{FailureCause, PoolError};
use crate::wire::answer::{ANSWER_WORDS, Answer, BlockKind, rows_of};
use crate::wire::record::EnvRecord;
use crate::wire::slot_layout::SlotRows;
use crate::wire::{EnvFault, calls, env_fault_path, env_fault_path_of, extra_apart_path};

/// Extra info that travelled beside an answer (it did not fit its env's room), as
/// `(env, bytes)`.
pub(super) type Apart = Vec<(usize, Vec<u8>)>;

/// A worker's answer, taken and checked ([`Supervisor::take_checked`]).
pub(super) struct Taken {
    pub(super) answer: Answer,
    /// The extra info that travelled beside it.
    pub(super) apart: Apart,
    /// It answers a restart of the worker (its envs' rows are marked restarted), by plan
    /// (`recycled`) or after a failure.
    pub(super) restart: bool,
    pub(super) recycled: bool,
    /// When the worker published it (`CLOCK_MONOTONIC`, ns).
    pub(super) ready_ns: u64,
}

/// Runs of consecutive envs in one slot: what an answer's checks go over
/// ([`Supervisor::checked`]), one pass per run.
pub(super) type Runs = Vec<(Range<usize>, usize)>;

/// Append runs of envs `runs` to `out`, each in the slot of its first env (`slot_of`),
/// joined where consecutive in one slot.
pub(super) fn runs_into(
    runs: impl IntoIterator<Item = Range<usize>>,
    slot_of: impl Fn(usize) -> usize,
    out: &mut Runs,
) {
    for run in runs {
        let slot = slot_of(run.start);
        match out.last_mut() {
            Some((r, s)) if r.end == run.start && *s == slot => r.end = run.end,
            _ => out.push((run, slot)),
        }
    }
}

/// Env `e`'s extra info of a row in a slot (`rec`: its record there): in its room of the slot,
/// as long as its `extra_len` says (at most the room), or `apart`. The one joiner of extra
/// info, for whole-batch calls and the async API.
pub(super) fn slot_extra(
    w: &SlotRows,
    e: usize,
    rec: &EnvRecord,
    apart: Option<&[u8]>,
) -> Option<Vec<u8>> {
    if let Some(b) = apart {
        return Some(b.to_vec());
    }
    let len = rec.extra_len as usize;
    if len == 0 {
        return None;
    }
    // SAFETY: env `e`'s extra room of the slot, which its worker has answered: no command
    // writes it until the caller sends to `e` again.
    let room = unsafe { w.extra_rows(e..e + 1) };
    Some(room[..len.min(room.len())].to_vec())
}

impl Supervisor {
    /// Take every answer that has arrived from starting and pending workers.
    pub(super) fn poll_all(&mut self) -> Result<(), PoolError> {
        for k in 0..self.workers.len() {
            loop {
                let s = &mut self.workers[k];
                if !matches!(
                    s.state,
                    LinkState::Starting { .. } | LinkState::Pending { .. }
                ) {
                    break;
                }
                let Some(sample) = s.ports.try_recv()? else {
                    break;
                };
                let h = *sample.user_header();
                if h.generation != s.generation {
                    continue; // from a dead incarnation
                }
                if let Some(stats) = &self.stats {
                    stats.took(k); // the worker may answer again (see `worker/concurrent.rs`)
                }
                if s.partial && matches!(s.state, LinkState::Pending { .. }) {
                    match BlockKind::from_word(h.kind) {
                        Some(BlockKind::Rows) => self.take_partial(k, &sample)?,
                        Some(BlockKind::Error) => self.take_partial_fault(k, &sample)?,
                        _ => {} // stale: nothing else answers a partial command
                    }
                    continue;
                }
                match (&s.state, BlockKind::from_word(h.kind)) {
                    (LinkState::Starting { then_reset, .. }, Some(BlockKind::Ready)) => {
                        if *then_reset {
                            drop(sample);
                            self.send_restart(k)?;
                        } else {
                            s.state = LinkState::Idle;
                        }
                    }
                    (LinkState::Pending { .. }, Some(BlockKind::Data)) if h.seq == s.seq => {
                        s.restart_streak = 0;
                        // The worker wrote its envs' books for this answer.
                        s.delivered = Some(h.seq);
                        s.first_episodes = false;
                        s.state = LinkState::Ready(Arrived::of(&sample));
                        self.arrived.push_back(k);
                    }
                    (LinkState::Pending { .. }, Some(BlockKind::Call)) if h.seq == s.seq => {
                        s.restart_streak = 0;
                        s.state = LinkState::Idle;
                    }
                    (LinkState::Pending { .. }, Some(BlockKind::Error)) if h.seq == s.seq => {
                        drop(sample);
                        s.restart_streak = 0;
                        s.state = LinkState::Idle;
                        let path = env_fault_path(&self.id, k, s.generation);
                        let fault = EnvFault::take(&path).unwrap_or_else(|e| {
                            EnvFault::new(
                                self.blocks[k].start as u64,
                                "a command",
                                format!("an env of the worker failed; {e}"),
                            )
                        });
                        self.failures.must_reset = true;
                        self.call.faults.push(PoolError::EnvFailed {
                            fault: Box::new(fault),
                            worker: k,
                            pid: s.pid,
                        });
                    }
                    _ => {} // stale answer: drop it
                }
            }
        }
        Ok(())
    }

    /// Worker `k`'s answer for envs of its partial commands, done one by one (its envs run on
    /// threads): they are ready, their rows in their slots, checked as any answer is; a bad
    /// answer is the worker's failure.
    fn take_partial(&mut self, k: usize, sample: &BlockSample) -> Result<(), PoolError> {
        let answer = Arrived::of(sample);
        let block = self.blocks[k].clone();
        let rows = match rows_of(sample.payload(), ANSWER_WORDS, block.len()) {
            Ok(rows) => rows,
            Err(what) => {
                return self.lose_corrupt(k, format!("its answer {}: {what}", answer.seq));
            }
        };
        let envs: Vec<usize> = rows.iter().map(|&j| block.start + j).collect();
        let mut at = Runs::new();
        runs_into(
            envs.iter().map(|&e| e..e + 1),
            |e| self.async_api.envs.last_slot(e),
            &mut at,
        );
        let Some((decoded, apart)) = self.checked(k, &answer, &at)? else {
            return Ok(());
        };
        if let Err(what) = self.async_api.envs.arrive_rows(k, &envs, &decoded, apart) {
            return self.lose_corrupt(k, format!("its answer {}: {what}", answer.seq));
        }
        self.workers[k].restart_streak = 0;
        self.settle_partial(k);
        Ok(())
    }

    /// Worker `k`'s report of an env of a partial command that failed: raised with the call's
    /// other failures (the caller resets), the env no longer in flight.
    fn take_partial_fault(&mut self, k: usize, sample: &BlockSample) -> Result<(), PoolError> {
        let n = sample.user_header().seq;
        let block = self.blocks[k].clone();
        let rows = match rows_of(sample.payload(), 0, block.len()) {
            Ok(rows) if rows.len() == 1 => rows,
            Ok(rows) => {
                return self.lose_corrupt(k, format!("an error answer naming {} envs", rows.len()));
            }
            Err(what) => return self.lose_corrupt(k, format!("its error answer {n}: {what}")),
        };
        let e = block.start + rows[0];
        let path = env_fault_path_of(&self.id, k, self.workers[k].generation, n);
        let fault = EnvFault::take(&path).unwrap_or_else(|why| {
            EnvFault::new(e as u64, "a command", format!("the env failed; {why}"))
        });
        self.async_api.envs.fail_row(k, e);
        self.failures.must_reset = true;
        self.call.faults.push(PoolError::EnvFailed {
            fault: Box::new(fault),
            worker: k,
            pid: self.workers[k].pid,
        });
        self.settle_partial(k);
        Ok(())
    }

    /// After an answer of worker `k`'s partial commands: idle once none of its envs is in
    /// flight, else pending since its oldest env in flight was sent (what `step_timeout`
    /// bounds).
    fn settle_partial(&mut self, k: usize) {
        let s = &mut self.workers[k];
        match self.async_api.envs.oldest_partial(k) {
            Some(since) if !self.async_api.envs.sent_to(k).is_empty() => {
                s.state = LinkState::Pending { since };
            }
            _ if self.async_api.envs.sent_to(k).is_empty() => {
                s.partial = false;
                s.idle();
            }
            _ => {}
        }
    }

    /// Decode and check worker `k`'s `answer` before anyone believes it: its words, the flag
    /// bytes of the rows it says it wrote (`rows`: runs of envs and the slot of each), and the
    /// extra info that travelled beside it. The answer and that extra info, or `None` when a
    /// check failed and the worker was handled as failed ([`FailureCause::Corrupt`]).
    pub(super) fn checked(
        &mut self,
        k: usize,
        answer: &Arrived,
        rows: &[(Range<usize>, usize)],
    ) -> Result<Option<(Answer, Apart)>, PoolError> {
        if let Some((_, slot)) = rows.iter().find(|(_, s)| *s >= self.slots.len()) {
            self.rows_of(*slot)?; // closed
        }
        let seq = answer.seq;
        let decoded = Answer::decode(&answer.words, self.slot_layout.extra_bytes)
            .and_then(|a| {
                for (envs, slot) in rows {
                    self.check_flags(&self.slots[*slot], envs.clone())?;
                }
                Ok(a)
            })
            .map_err(|what| format!("its answer to command {seq}: {what}"));
        let taken = match decoded {
            Ok(a) if a.apart => self.take_apart(k, seq).map(|apart| (a, apart)),
            Ok(a) => Ok((a, Vec::new())),
            Err(what) => Err(what),
        };
        match taken {
            Ok(v) => Ok(Some(v)),
            Err(what) => self.lose_corrupt(k, what).map(|()| None),
        }
    }

    /// Check the flag bytes a worker wrote in rows `envs` of a slot: those handed out as
    /// `bool` (`terminated`, `truncated`, the env's flag infos) and, in SAME_STEP mode,
    /// `has_final_obs`, which says which final observations to read.
    fn check_flags(&self, rows: &SlotRows, envs: Range<usize>) -> Result<(), String> {
        for &f in &self.flags {
            rows.check_flags(f, envs.clone())?;
        }
        Ok(())
    }

    /// Take worker `k`'s answer, which has arrived (it is idle again), checked over the rows
    /// `at` says it wrote (given whether it answers a restart of the worker: then every env of
    /// its block, which the supervisor marks restarted, their episodes having been cut).
    /// `None` when a check failed and the worker was handled as failed. The one taker of a
    /// worker's answer, for whole-batch calls and the async API.
    pub(super) fn take_checked(
        &mut self,
        k: usize,
        at: impl FnOnce(&Self, bool, &mut Runs),
    ) -> Result<Option<Taken>, PoolError> {
        let arrived = self.take_answer(k)?;
        let s = &mut self.workers[k];
        let restart = std::mem::take(&mut s.restarted);
        let recycled = std::mem::take(&mut s.recycled) && restart;
        // The runs' buffer is the supervisor's, reused answer after answer.
        let mut runs = std::mem::take(&mut self.runs);
        runs.clear();
        at(self, restart, &mut runs);
        let checked = self.checked(k, &arrived, &runs);
        if let (true, Ok(Some(_))) = (restart, &checked) {
            for (envs, slot) in &runs {
                let rows = self.rows_of(*slot)?;
                envs.clone().for_each(|e| rows.mark_restarted(e));
            }
        }
        self.runs = runs;
        Ok(checked?.map(|(answer, apart)| Taken {
            answer,
            apart,
            restart,
            recycled,
            ready_ns: arrived.ready_ns,
        }))
    }

    /// Worker `k`'s answer, which has arrived (it is idle again).
    pub(super) fn take_answer(&mut self, k: usize) -> Result<Arrived, PoolError> {
        let s = &mut self.workers[k];
        match std::mem::replace(&mut s.state, LinkState::Idle) {
            LinkState::Ready(answer) => Ok(answer),
            other => {
                s.state = other;
                Err(PoolError::State(format!("worker {k} has no answer ready")))
            }
        }
    }

    /// The extra info that did not fit its envs' rooms and travelled beside worker `k`'s
    /// answer `seq`, as `(env, bytes)`: the one reader of that side file. Each entry's row
    /// must be one of the worker's envs, once; an error says what was wrong.
    fn take_apart(&mut self, k: usize, seq: u64) -> Result<Apart, String> {
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
}
