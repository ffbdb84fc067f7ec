//! The async API's envs, one by one: where each env stands ([`Turn`]), the set of ready envs
//! in the order they were sent, and the worker blocks that hold their results.
//!
//! Service is fair by rule: the ready envs are handed over in the order they were sent, and
//! a `recv` waits a little for the env sent first when it is only a little late
//! ([`super::ready_set`]).
//!
//! Workers still answer one command at a time; this layer turns their answers into envs. An
//! env sent while its worker is busy is *staged* and goes with the worker's next command, with
//! any other envs of that worker staged meanwhile ([`crate::wire::Command::subset`] steps only those).
//! A block that arrives is held until the caller has received each of its ready envs; a worker
//! with many blocks held has the oldest copied out, so that its shared-memory samples never
//! run out.
//!
//! Rows in place: where the caller reads batches as views ([`AsyncEnvs::in_place`]), a step
//! command has its worker write each env's row at the env's row of a batch slot, one the
//! caller holds none of those envs' rows in ([`AsyncEnvs::target_for`]); a `recv` whose rows
//! are one run of envs in one slot hands them over as a view ([`Received::view`]), any other
//! is gathered. Resets and restarts answer by block (a restart resets envs the caller holds).

use std::collections::VecDeque;

use super::ready_set::ReadySet;

use crate::batch::Block;
use crate::wire::layout::EnvRecord;
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

/// One env's result, copied out of its block.
pub(super) struct Copied {
    rec: EnvRecord,
    obs: Vec<u8>,
    extra: Vec<u8>,
}

/// Where a ready env's result is.
enum Row {
    /// Row `j` of held block `b`.
    Held { b: usize, j: usize },
    /// A copy (its block was let go, or it answers a restart of an env the caller held).
    Copied(Box<Copied>),
    /// Written in place at the env's row of batch slot `slot`, with the extra info that did
    /// not fit its room (if any).
    InSlot { slot: usize, apart: Option<Vec<u8>> },
}

struct HeldBlock {
    block: Block,
    /// Ready envs whose rows are in it.
    users: usize,
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
    /// `Some((slot, first))`: the rows are envs `first..first + rows` in order, written in
    /// place in batch slot `slot`, where the caller reads them (observations, columns and
    /// extra room) until its next call; `obs` is then empty (`records` are copies of the
    /// rows' records). `None`: the rows are in `obs` and `records`.
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
    pub(super) turn: Vec<Turn>,
    /// Action words of staged envs, `aw` per env.
    staged: Vec<u64>,
    aw: usize,
    /// Staged envs, all workers together (nothing to dispatch when 0).
    pub(super) num_staged: usize,
    /// The envs of each worker's outstanding command.
    pub(super) sent: Vec<Vec<usize>>,
    /// The envs sent and not yet handed over, in the order they were sent.
    ready: ReadySet,
    rows: Vec<Option<Row>>,
    /// Its result answers a replacement by plan of its worker (`worker_recycled`).
    recycled: Vec<bool>,
    /// The first observation of an env the caller held when its worker was replaced: handed
    /// out at its next send (whose action is dropped).
    restarted: Vec<Option<Box<Copied>>>,
    blocks: Vec<Option<HeldBlock>>,
    free: Vec<usize>,
    /// Each worker's held blocks, oldest first.
    held_of: Vec<VecDeque<usize>>,
    /// The worker of each env.
    owner: Vec<usize>,
    /// Staged envs of each worker.
    staged_of: Vec<usize>,
    /// The batch slot of each env's row the caller received last, while it may still read it
    /// there (`None`: it was handed over as a copy).
    caller_slot: Vec<Option<usize>>,
    /// Batch slots step answers may be written in place in (0: none; they come by block).
    pub(super) in_place: usize,
    /// Of each env in flight under a partial command (its worker's envs run on threads and
    /// are answered one by one): the slot its rows go to, and the command it went with and
    /// when.
    partial: Vec<Option<(usize, u64, std::time::Instant)>>,
}

impl AsyncEnvs {
    /// The state of `num_envs` envs in `blocks` (one per worker), `aw` action words each.
    pub(super) fn new(blocks: &[std::ops::Range<usize>], aw: usize) -> Self {
        let num_envs = blocks.last().map_or(0, |b| b.end);
        let num_workers = blocks.len();
        let mut owner = vec![0; num_envs];
        for (k, b) in blocks.iter().enumerate() {
            owner[b.clone()].fill(k);
        }
        AsyncEnvs {
            owner,
            staged_of: vec![0; num_workers],
            caller_slot: vec![None; num_envs],
            in_place: 0,
            turn: vec![Turn::Caller; num_envs],
            staged: vec![0; num_envs * aw],
            aw,
            num_staged: 0,
            sent: vec![Vec::new(); num_workers],
            ready: ReadySet::new(num_envs),
            rows: (0..num_envs).map(|_| None).collect(),
            restarted: (0..num_envs).map(|_| None).collect(),
            recycled: vec![false; num_envs],
            blocks: Vec::new(),
            free: Vec::new(),
            held_of: vec![VecDeque::new(); num_workers],
            partial: vec![None; num_envs],
        }
    }

    /// Forget everything (a reset starts every env afresh); held blocks are let go.
    pub(super) fn clear(&mut self) {
        self.turn.fill(Turn::Caller);
        self.num_staged = 0;
        self.sent.iter_mut().for_each(Vec::clear);
        self.ready.clear();
        self.rows.iter_mut().for_each(|r| *r = None);
        self.restarted.iter_mut().for_each(|r| *r = None);
        self.recycled.fill(false);
        self.blocks.clear();
        self.free.clear();
        self.held_of.iter_mut().for_each(VecDeque::clear);
        self.staged_of.fill(0);
        self.caller_slot.fill(None);
        self.partial.fill(None);
    }

    /// Env `e` was sent just now: it takes the next ticket ([`ReadySet::sent`]).
    fn take_ticket(&mut self, e: usize) {
        self.ready.sent(e);
    }

    /// Env `e`'s result is ready.
    fn push_ready(&mut self, e: usize) {
        self.turn[e] = Turn::Ready;
        self.ready.ready(e);
    }

    /// See [`ReadySet::patience`].
    pub(super) fn patience(&self, now: std::time::Instant) -> Option<std::time::Instant> {
        self.ready.patience(now)
    }

    /// Envs whose result is ready.
    pub(super) fn num_ready(&self) -> usize {
        self.ready.len()
    }

    /// Envs sent and not yet received (staged, in flight or ready).
    pub(super) fn outstanding(&self) -> usize {
        self.turn.iter().filter(|t| **t != Turn::Caller).count()
    }

    /// The envs of worker `k`'s outstanding commands.
    pub(super) fn sent_to(&self, k: usize) -> &[usize] {
        &self.sent[k]
    }

    /// The envs of `envs` just dispatched (the last ones in worker `k`'s sent list) went with
    /// partial command `seq`, their rows to slot `slot`.
    pub(super) fn sent_partial(&mut self, k: usize, count: usize, slot: usize, seq: u64) {
        let now = std::time::Instant::now();
        let sent = &self.sent[k];
        for &e in &sent[sent.len().saturating_sub(count)..] {
            self.partial[e] = Some((slot, seq, now));
        }
    }

    /// The slot env `e`'s rows go to, if it is in flight under a partial command.
    pub(super) fn partial_slot(&self, e: usize) -> Option<usize> {
        self.partial[e].map(|(slot, _, _)| slot)
    }

    /// When the oldest env in flight with worker `k` under a partial command was sent.
    pub(super) fn oldest_partial(&self, k: usize) -> Option<std::time::Instant> {
        (self.sent[k].iter())
            .filter_map(|&e| self.partial[e].map(|(_, _, t)| t))
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
            let Some((slot, _, _)) = self.partial[e].take() else {
                continue;
            };
            self.sent[k].retain(|&x| x != e);
            let mine = apart
                .iter()
                .position(|(a, _)| *a == e)
                .map(|i| apart.swap_remove(i).1);
            self.recycled[e] = false;
            self.rows[e] = Some(Row::InSlot { slot, apart: mine });
            self.push_ready(e);
        }
        Ok(())
    }

    /// Env `e` of worker `k` failed under a partial command: it is no longer in flight (the
    /// failure is raised, and a reset starts it afresh).
    pub(super) fn fail_row(&mut self, k: usize, e: usize) {
        if self.partial[e].take().is_some() {
            self.sent[k].retain(|&x| x != e);
            self.turn[e] = Turn::Caller;
            self.ready.dropped(e);
        }
    }

    /// Every env of `envs` is in flight (a reset was sent to all of them).
    pub(super) fn all_in_flight(&mut self, k: usize, envs: std::ops::Range<usize>) {
        for e in envs.clone() {
            self.turn[e] = Turn::InFlight;
            self.take_ticket(e);
        }
        self.sent[k] = envs.collect();
    }

    /// Stage env `e`'s action words; or, if its worker was replaced while the caller held it,
    /// make its restart's first observation ready at once (the action is dropped, as a
    /// restarted env drops it in a sync step). Returns whether it was staged.
    pub(super) fn stage(&mut self, e: usize, words: &[u64]) -> bool {
        self.take_ticket(e);
        if let Some(c) = self.restarted[e].take() {
            self.rows[e] = Some(Row::Copied(c));
            self.push_ready(e);
            return false;
        }
        self.staged[e * self.aw..(e + 1) * self.aw].copy_from_slice(words);
        self.turn[e] = Turn::Staged;
        self.num_staged += 1;
        self.staged_of[self.owner[e]] += 1;
        true
    }

    /// Whether worker `k` has staged envs.
    pub(super) fn has_staged(&self, k: usize) -> bool {
        self.staged_of[k] > 0
    }

    /// The batch slot (0-based) worker `k`'s next step of `envs` may write its rows in: one
    /// where the caller holds none of the rows of the envs it steps, or `None` (answer by
    /// block) when step answers do not go in place or no slot is free of them.
    pub(super) fn target_for(&self, envs: std::ops::Range<usize>, only: &[u64]) -> Option<usize> {
        if self.in_place == 0 {
            return None;
        }
        let mut busy = 0u64;
        for (j, e) in envs.enumerate() {
            if only.get(j).is_none_or(|&w| w != 0)
                && let Some(s) = self.caller_slot[e]
            {
                busy |= 1 << s.min(63);
            }
        }
        (0..self.in_place.min(64)).find(|s| busy & (1 << s) == 0)
    }

    /// Which envs of `envs` (a worker's block) are staged: one word each, 1 or 0.
    pub(super) fn staged_rows(&self, envs: std::ops::Range<usize>) -> Vec<u64> {
        envs.map(|e| u64::from(self.turn[e] == Turn::Staged))
            .collect()
    }

    /// Take the staged envs of `envs` (worker `k`'s) for its next command: they are in flight
    /// from now. Returns their action words (`aw` per env of `envs`, zero for the others) and
    /// whether each steps; `None` if none is staged.
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
        let mut only = vec![0u64; envs.len()];
        for (j, e) in envs.clone().enumerate() {
            if self.turn[e] == Turn::Staged {
                words[j * aw..(j + 1) * aw].copy_from_slice(&self.staged[e * aw..(e + 1) * aw]);
                only[j] = 1;
                self.turn[e] = Turn::InFlight;
                self.sent[k].push(e);
                self.num_staged -= 1;
            }
        }
        Some((words, only))
    }

    /// Worker `k`'s answer to its outstanding command, for `envs` (its block): the envs it
    /// stepped become ready, in row order. A restart's answer (it reset every env of the
    /// block) also replaces the results of its envs that wait in the queue, drops the actions
    /// staged for the others, and keeps the first observation of each env the caller holds
    /// for its next send. `recycled`: the restart was a replacement by plan. Blocks beyond
    /// `keep` held for this worker are copied out.
    pub(super) fn arrive(&mut self, k: usize, block: Block, keep: usize, recycled: bool) {
        let start = block.env_ids().start;
        let n = block.env_ids().len();
        let b = self.hold(block);
        let sent = std::mem::take(&mut self.sent[k]);
        for &e in &sent {
            self.partial[e] = None; // a restart's answer covers its partial envs too
        }
        if !self.block(b).restarted() {
            for e in sent {
                self.recycled[e] = false;
                self.make_ready(e, b, e - start);
            }
        } else {
            for j in 0..n {
                let e = start + j;
                self.recycled[e] = recycled;
                match self.turn[e] {
                    Turn::InFlight => self.make_ready(e, b, j),
                    Turn::Staged => {
                        self.num_staged -= 1;
                        self.staged_of[k] -= 1;
                        self.make_ready(e, b, j);
                    }
                    Turn::Ready => {
                        let old = self.rows[e].replace(Row::Held { b, j });
                        self.release(old);
                        self.use_block(b);
                    }
                    Turn::Caller => {
                        self.restarted[e] = Some(Box::new(self.copy_row(b, j)));
                    }
                }
            }
        }
        if self.blocks[b].as_ref().is_some_and(|h| h.users == 0) {
            self.blocks[b] = None;
            self.free.push(b);
            return;
        }
        self.held_of[k].push_back(b);
        while self.held_of[k].len() > keep.max(1) {
            let Some(old) = self.held_of[k].pop_front() else {
                break;
            };
            self.copy_out(old, start..start + n);
        }
    }

    /// Worker `k`'s answer to its outstanding step, written in place in batch slot `slot`: the
    /// envs it stepped become ready, in row order. `apart`: `(env, bytes)` of the extra info
    /// that did not fit the envs' rooms.
    pub(super) fn arrive_in_slot(&mut self, k: usize, slot: usize, apart: Vec<(usize, Vec<u8>)>) {
        let sent = std::mem::take(&mut self.sent[k]);
        let mut apart = apart.into_iter().peekable();
        for e in sent {
            self.recycled[e] = false;
            let mine = apart.next_if(|(a, _)| *a == e).map(|(_, b)| b);
            self.rows[e] = Some(Row::InSlot { slot, apart: mine });
            self.push_ready(e);
        }
    }

    /// Hand over up to `n` ready envs, the one sent first first. `slots`: each batch slot's rows, to
    /// read the rows written in place; rows that are one run of envs in one slot are handed
    /// over as a view of it (see [`Received::view`]).
    pub(super) fn take(&mut self, n: usize, obs_bytes: usize, slots: &[SlotRows]) -> Received {
        let n = n.min(self.ready.len());
        if let Some(got) = self.take_view(n, slots) {
            return got;
        }
        let mut out = Received {
            env_ids: Vec::with_capacity(n),
            records: Vec::with_capacity(n),
            obs: Vec::with_capacity(n * obs_bytes),
            extras: Vec::new(),
            recycled: Vec::new(),
            view: None,
        };
        for r in 0..n {
            let Some(e) = self.ready.pop() else {
                break;
            };
            self.turn[e] = Turn::Caller;
            if std::mem::take(&mut self.recycled[e]) {
                out.recycled.push(e);
            }
            let row = self.rows[e].take();
            match &row {
                Some(Row::Held { b, j }) => {
                    let block = self.block(*b);
                    let rec = block.record(*j);
                    out.obs
                        .extend_from_slice(&block.obs()[j * obs_bytes..(j + 1) * obs_bytes]);
                    if rec.extra_len > 0 && !block.restarted() {
                        out.extras.push((r, block.extra(*j).to_vec()));
                    }
                    out.records.push(rec);
                }
                Some(Row::Copied(c)) => {
                    out.obs.extend_from_slice(&c.obs);
                    if !c.extra.is_empty() {
                        out.extras.push((r, c.extra.clone()));
                    }
                    out.records.push(c.rec);
                }
                Some(Row::InSlot { slot, apart }) => {
                    let w = &slots[*slot];
                    let rec = w.read(e);
                    // SAFETY: env `e`'s rows of the slot: its worker answered, and no command
                    // writes them again until the caller sends to `e`.
                    out.obs.extend_from_slice(unsafe { w.obs_rows(e..e + 1) });
                    if let Some(extra) = in_slot_extra(w, e, &rec, apart.as_deref()) {
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
            self.caller_slot[e] = None;
            self.release(row);
        }
        out
    }

    /// The next `n` ready envs as a view, when they are one run of envs `first..first + n` in
    /// order, written in place in one slot, with no extra info apart (else `None`, nothing
    /// taken). Extra info in the rows' rooms is copied out (`extras`).
    fn take_view(&mut self, n: usize, slots: &[SlotRows]) -> Option<Received> {
        let first = self.ready.first()?;
        let slot = match self.rows[first] {
            Some(Row::InSlot { slot, apart: None }) => slot,
            _ => return None,
        };
        let run = self.ready.peek(n).enumerate().all(|(i, e)| {
            e == first + i
                && !self.recycled[e]
                && matches!(self.rows[e], Some(Row::InSlot { slot: s, apart: None }) if s == slot)
        });
        if !run || n == 0 {
            return None;
        }
        let w = slots.get(slot)?;
        let env_ids: Vec<usize> = (0..n).filter_map(|_| self.ready.pop()).collect();
        let mut extras = Vec::new();
        let mut records = Vec::with_capacity(n);
        for (r, &e) in env_ids.iter().enumerate() {
            self.turn[e] = Turn::Caller;
            self.rows[e] = None;
            self.caller_slot[e] = Some(slot);
            let rec = w.read(e);
            if let Some(x) = in_slot_extra(w, e, &rec, None) {
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

    fn block(&self, b: usize) -> &Block {
        &self.blocks[b].as_ref().expect("a held block").block
    }

    fn hold(&mut self, block: Block) -> usize {
        let h = Some(HeldBlock { block, users: 0 });
        match self.free.pop() {
            Some(b) => {
                self.blocks[b] = h;
                b
            }
            None => {
                self.blocks.push(h);
                self.blocks.len() - 1
            }
        }
    }

    fn use_block(&mut self, b: usize) {
        if let Some(h) = self.blocks[b].as_mut() {
            h.users += 1;
        }
    }

    fn make_ready(&mut self, e: usize, b: usize, j: usize) {
        self.rows[e] = Some(Row::Held { b, j });
        self.use_block(b);
        self.push_ready(e);
    }

    /// A row is no longer needed: its block goes once no ready env needs it.
    fn release(&mut self, row: Option<Row>) {
        let Some(Row::Held { b, .. }) = row else {
            return;
        };
        let Some(h) = self.blocks[b].as_mut() else {
            return;
        };
        h.users -= 1;
        if h.users == 0 {
            let k = h.block.worker();
            self.blocks[b] = None;
            self.free.push(b);
            self.held_of[k].retain(|&x| x != b);
        }
    }

    fn copy_row(&self, b: usize, j: usize) -> Copied {
        let block = self.block(b);
        let rec = block.record(j);
        let ob = block.obs().len() / block.env_ids().len().max(1);
        Copied {
            rec,
            obs: block.obs()[j * ob..(j + 1) * ob].to_vec(),
            extra: if rec.extra_len > 0 && !block.restarted() {
                block.extra(j).to_vec()
            } else {
                Vec::new()
            },
        }
    }

    /// Copy the rows of block `b` that ready envs of `envs` still need, and let it go.
    fn copy_out(&mut self, b: usize, envs: std::ops::Range<usize>) {
        if self.blocks[b].is_none() {
            return;
        }
        for e in envs {
            if let Some(Row::Held { b: bb, j }) = self.rows[e]
                && bb == b
            {
                self.rows[e] = Some(Row::Copied(Box::new(self.copy_row(b, j))));
            }
        }
        self.blocks[b] = None;
        self.free.push(b);
    }
}

/// Env `e`'s extra info of a row written in place: in its room of the slot, or `apart`.
fn in_slot_extra(w: &SlotRows, e: usize, rec: &EnvRecord, apart: Option<&[u8]>) -> Option<Vec<u8>> {
    if let Some(b) = apart {
        return Some(b.to_vec());
    }
    let len = rec.extra_len as usize;
    if len == 0 {
        return None;
    }
    // SAFETY: env `e`'s extra room of the slot, as its obs rows above.
    let room = unsafe { w.extra_rows(e..e + 1) };
    Some(room[..len.min(room.len())].to_vec())
}
