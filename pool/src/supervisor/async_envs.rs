//! The async API's envs, one by one: where each env stands ([`Turn`]), the set of ready envs
//! in the order they were sent, and the batch slot each env's rows are in.
//!
//! Service is fair by rule: the ready envs are handed over in the order they were sent, and
//! a `recv` waits a little for the env sent first when it is only a little late
//! ([`super::ready_set`]).
//!
//! Workers still answer one command at a time; this layer turns their answers into envs. An
//! env sent while its worker is busy is *staged* and goes with the worker's next command, with
//! any other envs of that worker staged meanwhile ([`crate::wire::Command::subset`] serves only
//! those).
//!
//! Every answer's rows are in the batch slots. Each env's answers take turns over the slots
//! ([`AsyncEnvs::slot_for`]): the next goes to the slot after the one its latest answer is in,
//! skipping the slots the caller has lent out, so that the rows a caller received last (a view
//! of its slot, [`Received::view`]) stay put until that env's next answer but one; a
//! whole-batch call counts as every env's latest answer. A `recv` whose rows are one run of
//! envs in one slot hands them over as a view where the caller asks for views; any other is
//! gathered.

use std::time::Instant;

use super::intake::slot_extra;
use super::ready_set::ReadySet;

use crate::wire::record::EnvRecord;
use crate::wire::slot_layout::SlotRows;

/// Where an env stands in the async API.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Turn {
    /// With the caller (received, or never sent): it may be sent.
    Caller,
    /// Sent while its worker was busy: its action waits for the worker's next command.
    Staged,
    /// Its worker is stepping (or resetting) it.
    InFlight,
    /// Its result waits in the ready queue.
    Ready,
}

/// A ready env's result: its rows of batch slot `slot`, with the extra info that did not fit
/// its room (if any); `restart`: it answers a restart of its worker (its row says so, and
/// carries no extra info).
#[derive(Debug)]
struct Row {
    slot: usize,
    apart: Option<Vec<u8>>,
    restart: bool,
}

/// What one `recv` hands over: ready envs, first ready first.
#[derive(Debug, Default)]
pub struct Received {
    /// The envs of the rows.
    pub env_ids: Vec<usize>,
    /// Their records (restart flags applied).
    pub records: Vec<EnvRecord>,
    /// Their observations, `rows x obs_bytes` bytes.
    pub obs: Vec<u8>,
    /// `(row, bytes)` of the rows whose env wrote extra info.
    pub extras: Vec<(usize, Vec<u8>)>,
    /// The envs of rows whose worker was replaced by plan ([`crate::Pool::recycled_envs`]).
    pub recycled: Vec<usize>,
    /// `Some((slot, first))`: the rows are envs `first..first + rows` in order, in batch slot
    /// `slot`, where the caller reads them (observations, columns and extra room) until those
    /// envs' next answer but one; `obs` is then empty (`records` are copies of the rows'
    /// records). `None`: the rows are in `obs` and `records`.
    pub view: Option<(usize, usize)>,
}

impl Received {
    /// Write the rows' records into `columns`, row `r` at index `r` (a binding's `recv`
    /// columns: the layout of a slot's columns, rows in receive order). Returns whether some
    /// row reports a restart.
    pub fn write_columns(&self, columns: &SlotRows) -> bool {
        let mut restarted = false;
        for (r, rec) in self.records.iter().enumerate() {
            columns.record(r, rec);
            restarted |= rec.restarted();
        }
        restarted
    }
}

/// The async API's per-env state (see the module docs).
pub(super) struct AsyncEnvs {
    turn: Vec<Turn>,
    /// Envs not with the caller (staged, in flight or ready), kept with `turn`.
    outstanding: usize,
    /// Action words of staged envs, `aw` per env.
    staged: Vec<u64>,
    aw: usize,
    /// Staged envs, all workers together (nothing to dispatch when 0).
    pub(super) num_staged: usize,
    /// The envs of each worker's outstanding commands.
    pub(super) sent: Vec<Vec<usize>>,
    /// The envs sent and not yet handed over, in the order they were sent.
    ready: ReadySet,
    rows: Vec<Option<Row>>,
    /// Its result answers a replacement by plan of its worker (`worker_recycled`).
    recycled: Vec<bool>,
    /// The first rows of an env the caller held when its worker was restarted: handed out at
    /// its next send (whose action is dropped).
    restarted: Vec<Option<Row>>,
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
    /// Slots the caller has lent out (bit `s`: slot `s`): no answer is written there.
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
    pub(super) fn new(blocks: &[std::ops::Range<usize>], aw: usize, slots: usize) -> Self {
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
            sent: vec![Vec::new(); num_workers],
            ready: ReadySet::new(num_envs),
            rows: (0..num_envs).map(|_| None).collect(),
            restarted: (0..num_envs).map(|_| None).collect(),
            recycled: vec![false; num_envs],
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
        self.rows.iter_mut().for_each(|r| *r = None);
        self.restarted.iter_mut().for_each(|r| *r = None);
        self.recycled.fill(false);
        self.staged_of.fill(0);
        self.partial.fill(None);
    }

    /// A whole-batch call answered every env in slot `slot`: their latest answer.
    pub(super) fn whole_call(&mut self, slot: usize) {
        self.epoch += 1;
        self.whole_slot = slot;
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

    /// Env `e` was sent just now: it takes the next ticket ([`ReadySet::sent`]).
    fn take_ticket(&mut self, e: usize) {
        self.ready.sent(e);
    }

    /// Env `e`'s result is ready.
    fn push_ready(&mut self, e: usize) {
        self.set_turn(e, Turn::Ready);
        self.ready.ready(e);
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

    /// The envs of worker `k`'s outstanding commands.
    pub(super) fn sent_to(&self, k: usize) -> &[usize] {
        &self.sent[k]
    }

    /// The last `count` envs dispatched to worker `k` went with partial command `seq`.
    pub(super) fn sent_partial(&mut self, k: usize, count: usize, seq: u64) {
        let now = Instant::now();
        let sent = &self.sent[k];
        for &e in &sent[sent.len().saturating_sub(count)..] {
            self.partial[e] = Some((seq, now));
        }
    }

    /// When the oldest env in flight with worker `k` under a partial command was sent.
    pub(super) fn oldest_partial(&self, k: usize) -> Option<Instant> {
        (self.sent[k].iter())
            .filter_map(|&e| self.partial[e].map(|(_, t)| t))
            .min()
    }

    /// Envs `envs` of worker `k`, in flight under partial commands, are done: their rows are in
    /// their slots, and `apart` has the extra info that did not fit their rooms. An env not in
    /// flight so is the worker's error (the string says which), and nothing is taken.
    pub(super) fn arrive_rows(
        &mut self,
        k: usize,
        envs: &[usize],
        mut apart: Vec<(usize, Vec<u8>)>,
    ) -> Result<(), String> {
        if let Some(&e) = envs
            .iter()
            .find(|&&e| self.partial[e].is_none() || !self.sent[k].contains(&e))
        {
            return Err(format!(
                "an answer for env {e}, which is not in flight with it"
            ));
        }
        for &e in envs {
            if self.partial[e].take().is_none() {
                continue;
            }
            self.sent[k].retain(|&x| x != e);
            let mine = apart
                .iter()
                .position(|(a, _)| *a == e)
                .map(|i| apart.swap_remove(i).1);
            self.recycled[e] = false;
            self.rows[e] = Some(Row {
                slot: self.last_slot(e),
                apart: mine,
                restart: false,
            });
            self.push_ready(e);
        }
        Ok(())
    }

    /// Env `e` of worker `k` failed under a partial command: it is no longer in flight (the
    /// failure is raised, and a reset starts it afresh).
    pub(super) fn fail_row(&mut self, k: usize, e: usize) {
        if self.partial[e].take().is_some() {
            self.sent[k].retain(|&x| x != e);
            self.set_turn(e, Turn::Caller);
            self.ready.dropped(e);
        }
    }

    /// Every env of `envs` (worker `k`'s block) is in flight (a reset was sent to all of
    /// them); the slot of each (`s + 1`), in block order.
    pub(super) fn all_in_flight(&mut self, k: usize, envs: std::ops::Range<usize>) -> Vec<u64> {
        let targets = envs
            .clone()
            .map(|e| {
                self.set_turn(e, Turn::InFlight);
                self.take_ticket(e);
                self.slot_for(e) as u64 + 1
            })
            .collect();
        self.sent[k] = envs.collect();
        targets
    }

    /// The slot (`s + 1`) of each env of `envs` (worker `k`'s block) for a reset of them all
    /// that restarts the worker: where an env in flight or ready is written already (its row
    /// is replaced), the next slot of any other. `uniform`: one slot for the whole block (a
    /// vector env per worker writes its block in one), the first env's.
    pub(super) fn restart_targets(
        &mut self,
        envs: std::ops::Range<usize>,
        uniform: bool,
    ) -> Vec<u64> {
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

    /// Stage env `e`'s action words; or, if its worker was restarted while the caller held it,
    /// make its restart's first rows ready at once (the action is dropped, as a restarted env
    /// drops it in a sync step). Returns whether it was staged.
    pub(super) fn stage(&mut self, e: usize, words: &[u64]) -> bool {
        self.take_ticket(e);
        if let Some(row) = self.restarted[e].take() {
            self.rows[e] = Some(row);
            self.push_ready(e);
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
        envs: std::ops::Range<usize>,
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
                self.sent[k].push(e);
                self.num_staged -= 1;
            }
        }
        Some((words, targets))
    }

    /// Worker `k`'s answer to its outstanding command: the envs it served become ready, in row
    /// order, each with its share of `apart` (`(env, bytes)` of the extra info that did not fit
    /// the rooms). `restart`: the answer is a reset of every env of `block` that restarted the
    /// worker (`Some(true)`: a replacement by plan); it also replaces the results of its envs
    /// that wait in the queue, drops the actions staged for the others, and keeps the first
    /// rows of each env the caller holds for its next send.
    pub(super) fn arrive(
        &mut self,
        k: usize,
        block: std::ops::Range<usize>,
        apart: Vec<(usize, Vec<u8>)>,
        restart: Option<bool>,
    ) {
        let sent = std::mem::take(&mut self.sent[k]);
        for &e in &sent {
            self.partial[e] = None; // a restart's answer covers its partial envs too
        }
        let Some(recycled) = restart else {
            let mut apart = apart.into_iter().peekable();
            for e in sent {
                self.recycled[e] = false;
                let mine = apart.next_if(|(a, _)| *a == e).map(|(_, b)| b);
                self.rows[e] = Some(Row {
                    slot: self.last_slot(e),
                    apart: mine,
                    restart: false,
                });
                self.push_ready(e);
            }
            return;
        };
        for e in block {
            self.recycled[e] = recycled;
            let row = Row {
                slot: self.last_slot(e),
                apart: None,
                restart: true,
            };
            match self.turn[e] {
                Turn::InFlight => {
                    self.rows[e] = Some(row);
                    self.push_ready(e);
                }
                Turn::Staged => {
                    self.num_staged -= 1;
                    self.staged_of[k] -= 1;
                    self.rows[e] = Some(row);
                    self.push_ready(e);
                }
                Turn::Ready => self.rows[e] = Some(row),
                Turn::Caller => self.restarted[e] = Some(row),
            }
        }
    }

    /// Hand over up to `n` ready envs, the one sent first first. `slots`: each batch slot's
    /// rows; rows that are one run of envs in one slot are handed over as a view of it where
    /// the caller asks for views (see [`Received::view`]).
    pub(super) fn take(&mut self, n: usize, obs_bytes: usize, slots: &[SlotRows]) -> Received {
        let n = n.min(self.ready.len());
        if self.views
            && let Some(got) = self.take_view(n, slots)
        {
            return got;
        }
        let mut out = Received {
            env_ids: Vec::with_capacity(n),
            records: Vec::with_capacity(n),
            obs: Vec::with_capacity(n * obs_bytes),
            ..Default::default()
        };
        for r in 0..n {
            let Some(e) = self.ready.pop() else {
                break;
            };
            self.set_turn(e, Turn::Caller);
            if std::mem::take(&mut self.recycled[e]) {
                out.recycled.push(e);
            }
            match self.rows[e].take() {
                Some(row) => {
                    let w = &slots[row.slot];
                    let rec = w.read(e);
                    // SAFETY: env `e`'s rows of the slot: its worker answered, and no command
                    // writes them again until the caller sends to `e`.
                    out.obs.extend_from_slice(unsafe { w.obs_rows(e..e + 1) });
                    if !row.restart
                        && let Some(extra) = slot_extra(w, e, &rec, row.apart.as_deref())
                    {
                        out.extras.push((r, extra));
                    }
                    out.records.push(rec);
                }
                None => {
                    out.obs.resize(out.obs.len() + obs_bytes, 0);
                    out.records.push(EnvRecord::default());
                }
            }
            out.env_ids.push(e);
        }
        out
    }

    /// The next `n` ready envs as a view, when they are one run of envs `first..first + n` in
    /// order, in one slot, with no extra info apart and no restart (else `None`, nothing
    /// taken). Extra info in the rows' rooms is copied out (`extras`).
    fn take_view(&mut self, n: usize, slots: &[SlotRows]) -> Option<Received> {
        let first = self.ready.first()?;
        let plain = |row: &Option<Row>| match row {
            Some(r) if r.apart.is_none() && !r.restart => Some(r.slot),
            _ => None,
        };
        let slot = plain(&self.rows[first])?;
        let run = self.ready.peek(n).enumerate().all(|(i, e)| {
            e == first + i && !self.recycled[e] && plain(&self.rows[e]) == Some(slot)
        });
        if !run || n == 0 {
            return None;
        }
        let w = slots.get(slot)?;
        let env_ids: Vec<usize> = (0..n).filter_map(|_| self.ready.pop()).collect();
        let mut extras = Vec::new();
        let mut records = Vec::with_capacity(n);
        for (r, &e) in env_ids.iter().enumerate() {
            self.set_turn(e, Turn::Caller);
            self.rows[e] = None;
            let rec = w.read(e);
            if let Some(x) = slot_extra(w, e, &rec, None) {
                extras.push((r, x));
            }
            records.push(rec);
        }
        Some(Received {
            env_ids,
            records,
            extras,
            view: Some((slot, first)),
            ..Default::default()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::slot_layout::SlotLayout;

    #[test]
    fn outstanding_envs_are_counted_through_every_turn() {
        // Two workers of two envs, one action word each, two slots.
        let mut envs = AsyncEnvs::new(&[0..2, 2..4], 1, 2);
        let (num_envs, obs_bytes, n_info, final_obs, extra_bytes) = (4, 8, 0, false, 0);
        let layout = SlotLayout {
            num_envs,
            obs_bytes,
            n_info,
            final_obs,
            extra_bytes,
        };
        let mut buf = vec![0u64; 2 * layout.bytes() / 8];
        // SAFETY: two slots of the layout's size, 8-aligned (the test does not need 64).
        let slots: Vec<SlotRows> = (0..2)
            .map(|s| unsafe { layout.rows(buf.as_mut_ptr().cast::<u8>().add(s * layout.bytes())) })
            .collect();
        assert_eq!(envs.outstanding(), 0);
        assert!(envs.stage(1, &[3]) && envs.stage(2, &[4]));
        assert_eq!(envs.outstanding(), 2, "staged envs are outstanding");
        let (words, targets) = envs.dispatch(0, 0..2).expect("env 1 is staged");
        assert_eq!(
            (words, targets),
            (vec![0, 3], vec![0, 1]),
            "env 1 into slot 0"
        );
        envs.arrive(0, 0..2, Vec::new(), None);
        assert_eq!((envs.outstanding(), envs.num_ready()), (2, 1));
        let got = envs.take(1, 8, &slots);
        assert_eq!((got.env_ids, envs.outstanding()), (vec![1], 1));
        // Worker 1 restarts: its staged env 2 is ready with the restart's rows; env 3, which
        // the caller holds, keeps them for its next send.
        envs.arrive(1, 2..4, Vec::new(), Some(false));
        assert_eq!((envs.outstanding(), envs.num_ready()), (1, 1));
        assert!(!envs.stage(3, &[0]), "its restart's rows are ready at once");
        assert_eq!((envs.outstanding(), envs.num_ready()), (2, 2));
        envs.clear();
        assert_eq!(envs.outstanding(), 0);
    }
}
