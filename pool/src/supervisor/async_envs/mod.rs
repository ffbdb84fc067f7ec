//! The pool's one lane, env by env: where each env stands ([`Turn`]), the ready set of runs
//! in the order they were sent ([`super::ready_set`]), and the batch slot each env's rows are
//! in. A whole-batch call is a send of every env (each worker block one run) and a receive
//! of all of them in env order; the async API sends any envs, each a run of its own, and
//! receives the first ready.
//!
//! Service is fair by rule: the ready envs are handed over in the order they were sent, and
//! a `recv` waits a little for the env sent first when it is only a little late
//! ([`super::ready_set`]).
//!
//! Workers answer one command at a time (a worker whose envs run on threads answers a partial
//! command env by env); this layer turns their answers into ready runs. An env sent while its
//! worker is busy is *staged* and goes with the worker's next command, with any other envs of
//! that worker staged meanwhile ([`crate::wire::Command::subset`] serves only those). The
//! envs of a partial command are followed one by one (`partial.rs`).
//!
//! Every answer's rows are in the batch slots. A whole-batch call writes every env into one
//! slot ([`AsyncEnvs::send_whole`]); an async env's answers take turns over the slots
//! ([`AsyncEnvs::slot_for`]): the next goes to the slot after the one its latest answer is in,
//! skipping the slots the caller has lent out, so that the rows a caller received last (a view
//! of its slot, [`Received::view`]) stay put until that env's next answer but one. Rows that
//! are one run of envs in one slot are handed over as a view where the caller asks for views
//! (a whole-batch call always does); any other are gathered.

mod partial;

use std::ops::Range;
use std::time::Instant;

use super::intake::Apart;
use super::ready_set::{HeldRestarts, ReadySet, Run, gather, view_extras};
use crate::batch::Received;
use crate::wire::answer::Answer;
use crate::wire::slot_layout::SlotRows;

/// Where an env stands in the lane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Turn {
    /// With the caller (received, or never sent): it may be sent.
    Caller,
    /// Sent while its worker was busy: its action waits for the worker's next command.
    Staged,
    /// Its worker is stepping (or resetting) it.
    InFlight,
    /// Its result waits in the ready set.
    Ready,
}

/// The lane's per-env state (see the module docs).
pub(super) struct AsyncEnvs {
    turn: Vec<Turn>,
    /// Envs not with the caller (staged, in flight or ready), kept with `turn`.
    outstanding: usize,
    /// Action words of staged envs, `aw` per env.
    staged: Vec<u64>,
    aw: usize,
    /// Staged envs, all workers together (nothing to dispatch when 0).
    pub(super) num_staged: usize,
    /// The runs of each worker's outstanding commands, in the order sent.
    sent: Vec<Vec<Range<usize>>>,
    /// The runs sent and not yet handed over, in the order they were sent.
    ready: ReadySet,
    /// The runs a receive took, reused receive after receive.
    taken: Vec<Run>,
    /// The first rows of each env the caller held when its worker was restarted: handed out
    /// at its next send (whose action is dropped) or whole-batch call.
    restarted: HeldRestarts,
    /// Envs the last whole-batch call answered so.
    handed_over: usize,
    /// The worker of each env.
    owner: Vec<usize>,
    /// Staged envs of each worker.
    staged_of: Vec<usize>,
    /// The slot of each env's latest answer, valid while its epoch is `epoch`; before that,
    /// the slot of the last whole-batch call (`whole_slot`), which answered every env.
    last: Vec<(u64, usize)>,
    epoch: u64,
    whole_slot: usize,
    /// Slots of the batch buffer.
    slots: usize,
    /// Slots the caller has lent out (bit `s`: slot `s`): no async answer is written there.
    pub(super) lent: u64,
    /// `recv` hands rows that are one run of envs in one slot over as a view.
    pub(super) views: bool,
    /// Of each env in flight under a partial command (its worker's envs run on threads and
    /// are answered one by one): the command it went with, and when.
    partial: Vec<Option<(u64, Instant)>>,
}

impl AsyncEnvs {
    /// The state of `num_envs` envs in `blocks` (one per worker), `aw` action words each, in a
    /// pool of `slots` batch slots.
    pub(super) fn new(blocks: &[Range<usize>], aw: usize, slots: usize) -> Self {
        let num_envs = blocks.last().map_or(0, |b| b.end);
        let num_workers = blocks.len();
        let mut owner = vec![0; num_envs];
        for (k, b) in blocks.iter().enumerate() {
            owner[b.clone()].fill(k);
        }
        AsyncEnvs {
            owner,
            staged_of: vec![0; num_workers],
            turn: vec![Turn::Caller; num_envs],
            outstanding: 0,
            staged: vec![0; num_envs * aw],
            aw,
            num_staged: 0,
            sent: blocks.iter().map(|b| Vec::with_capacity(b.len())).collect(),
            ready: ReadySet::new(num_envs),
            taken: Vec::with_capacity(num_workers),
            restarted: HeldRestarts::new(num_envs),
            handed_over: 0,
            // Epoch 0 is no epoch: before any answer, every env's latest is `whole_slot`.
            last: vec![(0, 0); num_envs],
            epoch: 1,
            // The first answers go to slot 0.
            whole_slot: slots - 1,
            slots,
            lent: 0,
            views: false,
            partial: vec![None; num_envs],
        }
    }

    /// Forget every env's turn (a reset starts every env afresh); where their rows are stays
    /// known.
    pub(super) fn clear(&mut self) {
        self.turn.fill(Turn::Caller);
        self.outstanding = 0;
        self.num_staged = 0;
        self.sent.iter_mut().for_each(Vec::clear);
        self.ready.clear();
        self.restarted.clear();
        self.staged_of.fill(0);
        self.partial.fill(None);
    }

    /// A whole-batch call is sent to every env (each worker's block of `blocks` one run, in
    /// block order), every answer into slot `slot` (of `rows`), their latest. Every env is
    /// with the caller before (`outstanding() == 0`). An env whose worker was restarted while
    /// the caller held it is answered by its restart's rows, copied into `slot` and ready at
    /// once (a run of its own, in its place), unless the call resets it (`resets`, a partial
    /// reset's mask): the call leaves it alone ([`AsyncEnvs::whole_targets`]).
    pub(super) fn send_whole(
        &mut self,
        slot: usize,
        blocks: &[Range<usize>],
        rows: &[SlotRows],
        resets: Option<&[bool]>,
    ) {
        self.epoch += 1;
        self.whole_slot = slot;
        self.turn.fill(Turn::InFlight);
        self.outstanding = self.turn.len();
        self.handed_over = 0;
        for (k, b) in blocks.iter().enumerate() {
            self.sent[k].clear();
            let start = match self.restarted.any() {
                true => self.hand_over(k, b.clone(), slot, rows, resets),
                false => b.start,
            };
            if start < b.end {
                self.ready.sent(start..b.end);
                self.sent[k].push(start..b.end);
            }
        }
    }

    /// [`AsyncEnvs::send_whole`] for the envs of `block` (worker `k`'s) whose restart is kept:
    /// each answered by it, the envs before it one run. Returns the first env after the last
    /// so answered (`block.start` when none).
    #[cold]
    fn hand_over(
        &mut self,
        k: usize,
        block: Range<usize>,
        slot: usize,
        rows: &[SlotRows],
        resets: Option<&[bool]>,
    ) -> usize {
        let mut start = block.start;
        for e in block {
            let Some(run) = self.restarted.take(e) else {
                continue;
            };
            if resets.is_some_and(|m| m[e]) {
                continue;
            }
            if start < e {
                self.ready.sent(start..e);
                self.sent[k].push(start..e);
            }
            if run.slot != slot {
                // SAFETY: no worker writes row `e` of either slot: the restart's answer is
                // in, and this call leaves the env alone.
                unsafe { rows[slot].copy_row(&rows[run.slot], e) };
            }
            self.ready.sent(e..e + 1);
            self.push_ready(Run { slot, ..run });
            self.handed_over += 1;
            start = e + 1;
        }
        start
    }

    /// The slot words of a whole-batch call's command to the envs `block` (one worker's) into
    /// slot `slot`: `None` when it goes to all of them (each into `slot`), else each env's
    /// (`slot + 1`, or 0 for an env answered already, [`AsyncEnvs::send_whole`]), all 0 when
    /// none needs the command.
    pub(super) fn whole_targets(&self, block: Range<usize>, slot: usize) -> Option<Vec<u64>> {
        if self.handed_over == 0 || !block.clone().any(|e| self.turn[e] == Turn::Ready) {
            return None;
        }
        let word = |e: usize| u64::from(self.turn[e] != Turn::Ready) * (slot as u64 + 1);
        Some(block.map(word).collect())
    }

    /// The slot env `e`'s latest answer is in (or goes to, while it is in flight).
    pub(super) fn last_slot(&self, e: usize) -> usize {
        match self.last[e] {
            (epoch, slot) if epoch == self.epoch => slot,
            _ => self.whole_slot,
        }
    }

    /// The slot env `e`'s next answer goes to, now noted as its latest: the first after the
    /// one its latest answer is in that the caller has not lent out (that one again when
    /// every other is lent).
    fn slot_for(&mut self, e: usize) -> usize {
        let last = self.last_slot(e);
        let slot = (1..=self.slots)
            .map(|i| (last + i) % self.slots)
            .find(|s| self.lent & (1 << s) == 0)
            .unwrap_or(last);
        self.last[e] = (self.epoch, slot);
        slot
    }

    /// Where env `e` stands.
    pub(super) fn turn(&self, e: usize) -> Turn {
        self.turn[e]
    }

    /// Env `e` stands at `t` now (the count of outstanding envs follows).
    fn set_turn(&mut self, e: usize, t: Turn) {
        let was = std::mem::replace(&mut self.turn[e], t);
        match (was == Turn::Caller, t == Turn::Caller) {
            (true, false) => self.outstanding += 1,
            (false, true) => self.outstanding -= 1,
            _ => {}
        }
    }

    /// The answer of run `run` is in: its envs are ready (a whole-range operation: a whole
    /// batch call's worker block is one).
    fn push_ready(&mut self, run: Run) {
        let turns = &mut self.turn[run.envs.clone()];
        self.outstanding += turns.iter().filter(|&&t| t == Turn::Caller).count();
        turns.fill(Turn::Ready);
        self.ready.ready(run);
    }

    /// See [`ReadySet::patience`].
    pub(super) fn patience(&self, now: Instant) -> Option<Instant> {
        self.ready.patience(now)
    }

    /// Envs whose result is ready.
    pub(super) fn num_ready(&self) -> usize {
        self.ready.len()
    }

    /// Envs sent and not yet received (staged, in flight or ready).
    pub(super) fn outstanding(&self) -> usize {
        self.outstanding
    }

    /// The runs of worker `k`'s outstanding commands.
    pub(super) fn sent_to(&self, k: usize) -> &[Range<usize>] {
        &self.sent[k]
    }

    /// The run of `envs` (sent together) as `answer` answers it, with its share of `apart`.
    fn answered(&self, envs: Range<usize>, answer: &Answer, apart: &mut Apart) -> Run {
        let mine = match apart.is_empty() {
            true => Vec::new(),
            false => apart.extract_if(.., |(e, _)| envs.contains(e)).collect(),
        };
        Run {
            slot: self.last_slot(envs.start),
            restart: false,
            recycled: false,
            extras: answer.extras,
            final_obs: answer.final_obs,
            apart: mine,
            envs,
        }
    }

    /// The slot (`s + 1`) of each env of `envs` (worker `k`'s block) for a reset of them all
    /// that restarts the worker: where an env in flight or ready is written already (its row
    /// is replaced), the next slot of any other. `uniform`: one slot for the whole block (a
    /// vector env per worker writes its block in one), the first env's.
    pub(super) fn restart_targets(&mut self, envs: Range<usize>, uniform: bool) -> Vec<u64> {
        let mut targets: Vec<u64> = envs
            .map(|e| match self.turn[e] {
                Turn::InFlight | Turn::Ready => self.last_slot(e) as u64 + 1,
                Turn::Staged | Turn::Caller => self.slot_for(e) as u64 + 1,
            })
            .collect();
        if uniform && let Some(&t) = targets.first() {
            targets.fill(t);
        }
        targets
    }

    /// Whether env `b`, sent right after env `a`, goes in `a`'s run: the next env of the same
    /// worker, its latest answer in the same slot (so its next goes to the same slot too),
    /// neither with a restart's rows waiting, and a worker that answers whole commands (not
    /// `concurrent`: its envs on threads, each answered as it finishes).
    pub(super) fn joins(&self, a: usize, b: usize, concurrent: bool) -> bool {
        let plain = |e: usize| !self.restarted.holds(e);
        let same_slot = self.last_slot(a) == self.last_slot(b);
        !concurrent
            && b == a + 1
            && self.owner[a] == self.owner[b]
            && same_slot
            && plain(a)
            && plain(b)
    }

    /// The envs `envs` are sent together, just now: one run, which takes the next ticket
    /// ([`ReadySet::sent`]). Stage each next.
    pub(super) fn sent_run(&mut self, envs: Range<usize>) {
        self.ready.sent(envs);
    }

    /// Stage env `e`'s action words (its run sent: [`AsyncEnvs::sent_run`]); or, if its worker
    /// was restarted while the caller held it, make its restart's first rows ready at once
    /// (the action is dropped, as a restarted env drops it in a sync step). Returns whether it
    /// was staged.
    pub(super) fn stage(&mut self, e: usize, words: &[u64]) -> bool {
        if let Some(run) = self.restarted.take(e) {
            self.push_ready(run);
            return false;
        }
        self.staged[e * self.aw..(e + 1) * self.aw].copy_from_slice(words);
        self.set_turn(e, Turn::Staged);
        self.num_staged += 1;
        self.staged_of[self.owner[e]] += 1;
        true
    }

    /// Whether worker `k` has staged envs.
    pub(super) fn has_staged(&self, k: usize) -> bool {
        self.staged_of[k] > 0
    }

    /// Take the staged envs of `envs` (worker `k`'s) for its next command: they are in flight
    /// from now. Returns their action words (`aw` per env of `envs`, zero for the others) and
    /// the slot each writes in (`s + 1`; 0 for the envs left alone); `None` if none is staged.
    pub(super) fn dispatch(
        &mut self,
        k: usize,
        envs: Range<usize>,
    ) -> Option<(Vec<u64>, Vec<u64>)> {
        let aw = self.aw;
        if self.staged_of[k] == 0 {
            return None;
        }
        self.staged_of[k] = 0;
        let mut words = vec![0u64; envs.len() * aw];
        let mut targets = vec![0u64; envs.len()];
        for (j, e) in envs.clone().enumerate() {
            if self.turn[e] == Turn::Staged {
                words[j * aw..(j + 1) * aw].copy_from_slice(&self.staged[e * aw..(e + 1) * aw]);
                targets[j] = self.slot_for(e) as u64 + 1;
                self.set_turn(e, Turn::InFlight);
                match self.sent[k].last_mut() {
                    // The next env of its run.
                    Some(r) if r.end == e && self.ready.same_run(r.start, e) => r.end += 1,
                    _ => self.sent[k].push(e..e + 1),
                }
                self.num_staged -= 1;
            }
        }
        Some((words, targets))
    }

    /// Worker `k`'s answer to its outstanding command (`answer`: what it said of its rows): the
    /// runs it served are ready, each with its share of `apart`. `restart`: the answer is a
    /// reset of every env of `block` that restarted the worker (`Some(true)`: a replacement by
    /// plan); it also replaces the results of its envs that are ready, drops the actions
    /// staged for the others, and keeps the first rows of each env the caller holds for its
    /// next send.
    pub(super) fn arrive(
        &mut self,
        k: usize,
        block: Range<usize>,
        answer: &Answer,
        mut apart: Apart,
        restart: Option<bool>,
    ) {
        let mut sent = std::mem::take(&mut self.sent[k]);
        for r in &sent {
            self.partial[r.clone()].fill(None); // a restart's answer covers its partial envs too
        }
        let Some(recycled) = restart else {
            for r in sent.drain(..) {
                let run = self.answered(r, answer, &mut apart);
                self.push_ready(run);
            }
            self.sent[k] = sent;
            return;
        };
        sent.clear();
        self.sent[k] = sent;
        let mut e = block.start;
        while e < block.end {
            let mut end = e + 1;
            match self.turn[e] {
                Turn::InFlight | Turn::Staged => {
                    while end < block.end
                        && self.turn[end] == self.turn[e]
                        && self.ready.same_run(e, end)
                    {
                        end += 1;
                    }
                    if self.turn[e] == Turn::Staged {
                        self.num_staged -= end - e;
                        self.staged_of[k] -= end - e;
                    }
                    let run = Run::restart(e..end, self.last_slot(e), recycled);
                    self.push_ready(run);
                }
                Turn::Ready => {
                    if let Some(run) = self.ready.ready_run(e) {
                        let slot = run.slot;
                        *run = Run::restart(run.envs.clone(), slot, recycled);
                    }
                }
                Turn::Caller => {
                    let run = Run::restart(e..e + 1, self.last_slot(e), recycled);
                    self.restarted.keep(e, run);
                }
            }
            e = end;
        }
    }

    /// Hand over up to `n` ready envs, the one sent first first: as a view of their slot when
    /// they are one run of envs in one slot and `view` (or the caller asked for views), else
    /// gathered. `slots`: each batch slot's rows.
    pub(super) fn take(
        &mut self,
        n: usize,
        view: bool,
        obs_bytes: usize,
        slots: &[SlotRows],
    ) -> Received {
        let mut runs = std::mem::take(&mut self.taken);
        runs.clear();
        let mut count = 0;
        while count < n {
            let Some(run) = self.ready.pop(n - count) else {
                break;
            };
            count += run.envs.len();
            runs.push(run);
        }
        let mut out = Received {
            env_ids: Vec::with_capacity(count),
            ..Default::default()
        };
        for run in &runs {
            // Ready envs all, with the caller from now.
            self.turn[run.envs.clone()].fill(Turn::Caller);
            self.outstanding -= run.envs.len();
            if run.recycled {
                out.recycled.extend(run.envs.clone());
            }
            out.restarted |= run.restart;
            out.final_obs |= run.final_obs;
            out.env_ids.extend(run.envs.clone());
        }
        let first = runs.first().map_or((0, 0), |r| (r.slot, r.envs.start));
        let one_run =
            (runs.windows(2)).all(|w| w[1].envs.start == w[0].envs.end && w[1].slot == first.0);
        if (view || self.views) && one_run && !runs.is_empty() {
            let w = &slots[first.0];
            if out.restarted {
                // The column is the supervisor's to vouch for (a worker cannot know it was
                // restarted): made right for every row of the view.
                for r in runs.iter().filter(|r| !r.restart) {
                    r.envs.clone().for_each(|e| w.clear_restarted(e));
                }
            }
            out.extras = view_extras(&runs, slots, first.1);
            out.view = Some(first);
        } else {
            gather(&runs, obs_bytes, slots, &mut out);
        }
        self.taken = runs;
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::answer::AnswerExtras;
    use crate::wire::slot_layout::SlotLayout;

    const PLAIN: Answer = Answer {
        final_obs: false,
        apart: false,
        extras: AnswerExtras::None,
    };

    /// Two slots of a pool of 4 envs (8-byte observations), in `buf`.
    fn slots(buf: &mut Vec<u64>) -> Vec<SlotRows> {
        let layout = SlotLayout {
            num_envs: 4,
            obs_bytes: 8,
            n_info: 0,
            final_obs: false,
            extra_bytes: 0,
        };
        *buf = vec![0u64; 2 * layout.bytes() / 8];
        // SAFETY: two slots of the layout's size, 8-aligned (the test does not need 64).
        (0..2)
            .map(|s| unsafe { layout.rows(buf.as_mut_ptr().cast::<u8>().add(s * layout.bytes())) })
            .collect()
    }

    #[test]
    fn a_whole_batch_call_is_every_env_received_in_env_order_as_a_view() {
        // Two workers of two envs; the second answers first.
        let mut buf = Vec::new();
        let slots = slots(&mut buf);
        let mut envs = AsyncEnvs::new(&[0..2, 2..4], 1, 2);
        envs.send_whole(1, &[0..2, 2..4], &slots, None);
        assert_eq!(envs.outstanding(), 4);
        envs.arrive(1, 2..4, &PLAIN, Vec::new(), None);
        envs.arrive(0, 0..2, &PLAIN, Vec::new(), None);
        assert_eq!(envs.num_ready(), 4);
        let got = envs.take(4, true, 8, &slots);
        assert_eq!(got.env_ids, vec![0, 1, 2, 3]);
        assert_eq!(got.view, Some((1, 0)), "every env in the call's slot");
        assert!(got.records.is_empty() && got.obs.is_empty() && !got.restarted);
        assert_eq!(envs.outstanding(), 0);
        // The next async answer of an env goes to the slot after the call's.
        envs.sent_run(3..4);
        assert!(envs.stage(3, &[1]));
        assert_eq!(envs.dispatch(1, 2..4), Some((vec![0, 1], vec![0, 1])));
    }

    #[test]
    fn outstanding_envs_are_counted_through_every_turn() {
        let mut buf = Vec::new();
        let slots = slots(&mut buf);
        let mut envs = AsyncEnvs::new(&[0..2, 2..4], 1, 2);
        assert_eq!(envs.outstanding(), 0);
        envs.sent_run(1..2);
        envs.sent_run(2..3);
        assert!(envs.stage(1, &[3]) && envs.stage(2, &[4]));
        assert_eq!(envs.outstanding(), 2, "staged envs are outstanding");
        let (words, targets) = envs.dispatch(0, 0..2).expect("env 1 is staged");
        assert_eq!(
            (words, targets),
            (vec![0, 3], vec![0, 1]),
            "env 1 into slot 0"
        );
        envs.arrive(0, 0..2, &PLAIN, Vec::new(), None);
        assert_eq!((envs.outstanding(), envs.num_ready()), (2, 1));
        let got = envs.take(1, false, 8, &slots);
        assert_eq!((got.env_ids, envs.outstanding()), (vec![1], 1));
        // Worker 1 restarts: its staged env 2 is ready with the restart's rows; env 3, which
        // the caller holds, keeps them for its next send.
        envs.arrive(1, 2..4, &PLAIN, Vec::new(), Some(false));
        assert_eq!((envs.outstanding(), envs.num_ready()), (1, 1));
        envs.sent_run(3..4);
        assert!(!envs.stage(3, &[0]), "its restart's rows are ready at once");
        assert_eq!((envs.outstanding(), envs.num_ready()), (2, 2));
        let got = envs.take(2, false, 8, &slots);
        // (The intake marks a restart's rows in the slot; here only the runs say so.)
        assert!(got.restarted && got.env_ids == [2, 3]);
        assert_eq!(envs.outstanding(), 0);
        envs.clear();
        assert_eq!(envs.outstanding(), 0);
    }
}
