//! Whole-batch calls: a step, reset or partial reset of every env, each per-env output written
//! by the workers in place into a slot of the shared batch buffer, where the caller reads it.
//!
//! Each call is a send ([`Pool::send_step`], [`Pool::send_reset`], whole or partial) and a
//! wait ([`Pool::wait`]); [`Pool::step`] and [`Pool::reset`] are the two at once.
//! [`Pool::read_rows`] copies an answer's rows out, for callers that want copies.

use std::time::{Duration, Instant};

use super::Pool;
use super::actions::Actions;
use super::async_api::RecvWant;
use super::commands::StepActions;
use super::link::Target;
use crate::batch::{BatchOutput, Received, SlotExtras};
use crate::error::PoolError;
use crate::wire::slot_layout::{SlotLayout, SlotRows};

/// A whole-batch call (step, reset, partial reset) sent to every worker and not yet received
/// (the supervisor's `call.sent`): when it was sent, and the same on the clock the workers
/// stamp their answers with (`CLOCK_MONOTONIC`, ns).
pub(super) struct SentCall {
    at: Instant,
    at_ns: u64,
}

impl SentCall {
    /// A whole-batch call, sent to every worker just now.
    fn now() -> Self {
        SentCall {
            at: Instant::now(),
            at_ns: rogue_gym_ipc::monotonic_ns(),
        }
    }
}

impl Pool {
    /// Step every env: `actions[i]` for env `i` (indices, `&[i64]`, or any [`Actions`]), and
    /// wait for the answers, written into the next batch slot (see [`Pool::send_step`] for how
    /// long a slot stays unchanged). See [`crate::AutoresetMode`] for what a step after or at
    /// an episode end returns.
    pub fn step<'a>(&mut self, actions: impl Into<Actions<'a>>) -> Result<Received, PoolError> {
        self.send_step(actions)?;
        self.collect(None)?
            .ok_or_else(|| PoolError::State("a step without a timeout timed out".into()))
    }

    /// Reset every env, or with `mask` the envs whose entry is true (see
    /// [`Pool::send_reset`]), and wait for the answers, written into the next batch slot.
    pub fn reset(&mut self, mask: Option<&[bool]>) -> Result<Received, PoolError> {
        self.send_reset(mask)?;
        self.collect(None)?
            .ok_or_else(|| PoolError::State("a reset without a timeout timed out".into()))
    }

    /// The first half of [`Pool::step`] (gymnasium's `step_async`): check the actions and send
    /// each worker its block of them, to be answered into the next batch slot, which it
    /// returns; the workers step while the caller does something else. Collect the answers
    /// with [`Pool::wait`]; a sync call in between fails (a reset abandons the step).
    ///
    /// Slots take turns ([`crate::PoolConfig::batch_slots`] of them, two by default): slot `s`
    /// stays unchanged until the call that writes `s` again, at the earliest the second call
    /// after the one that returned `s`. [`Pool::select_slot`] names the slot the next call
    /// writes.
    pub fn send_step<'a>(&mut self, actions: impl Into<Actions<'a>>) -> Result<usize, PoolError> {
        let actions = actions.into();
        self.begin_call()?;
        let n = self.sup.cfg.num_envs;
        actions.check(&self.sup.spec, n, |r| r)?;
        if self.sup.failures.must_reset {
            return Err(PoolError::State(
                "call reset() before step() (after creation or after a failure)".into(),
            ));
        }
        self.all_idle(true)?;
        // Planned replacements happen here, between two commands (see `recycling`).
        let mut replaced = false;
        for k in 0..self.sup.workers.len() {
            replaced |= self.sup.recycle_if_due(k)?;
        }
        if replaced {
            self.all_idle(true)?;
        }
        let slot = self.sup.send_whole(None);
        let ab = self.sup.spec.action_bytes;
        for k in 0..self.sup.workers.len() {
            let actions = StepActions::Rows(actions.rows(self.sup.blocks[k].clone(), ab));
            self.sup
                .send_share(k, slot, |c, t| c.send_step(k, actions, t, false).map(drop))?;
        }
        self.sup.call.sent = Some(SentCall::now());
        Ok(slot)
    }

    /// The first half of [`Pool::reset`] (gymnasium's `reset_async`); collect the answers with
    /// [`Pool::wait`]. Returns the slot they are written in.
    ///
    /// * `None`: a full reset: every env starts its next episode (episode index 0 at the first
    ///   reset). Results of outstanding async requests (or of a step interrupted by an error)
    ///   are discarded.
    /// * `Some(mask)`, one entry per env (gymnasium's `reset_mask`): envs with `mask[i]` start
    ///   their next scheduled episode (episode index + 1, its seed from the schedule), exactly
    ///   as a full reset would start it for them, so trajectories stay independent of the
    ///   worker count. The others keep their state (an episode that ended in NEXT_STEP mode is
    ///   still autoreset by the next step); the worker writes their current observation into
    ///   the slot again ([`crate::Env::observe`]), and their row describes their current
    ///   episode with reward 0 and no flags. A partial reset needs a full reset first (after
    ///   creation, [`Pool::set_seeds`] or a failure) and no outstanding async requests. A
    ///   worker restarted during the call resets all its envs (they report `restarted`).
    pub fn send_reset(&mut self, mask: Option<&[bool]>) -> Result<usize, PoolError> {
        self.begin_call()?;
        match mask {
            None => self.drain()?,
            Some(mask) => {
                if mask.len() != self.sup.cfg.num_envs {
                    return Err(PoolError::BadBuffer {
                        what: "reset mask",
                        expected: self.sup.cfg.num_envs,
                        got: mask.len(),
                    });
                }
                if self.sup.failures.must_reset {
                    return Err(PoolError::State(
                        "a partial reset needs every env started: call a full reset() first \
                         (after creation, set_seeds or a failure)"
                            .into(),
                    ));
                }
                self.all_idle(true)?;
            }
        }
        let slot = self.sup.send_whole(mask);
        for k in 0..self.sup.workers.len() {
            self.sup
                .send_share(k, slot, |c, t| c.send_reset(k, t, mask))?;
        }
        if mask.is_none() {
            self.sup.failures.must_reset = false;
        }
        self.sup.call.sent = Some(SentCall::now());
        Ok(slot)
    }

    /// The second half of a whole-batch call ([`Pool::send_step`], [`Pool::send_reset`]):
    /// wait at most `timeout` (and always within the call's bound, [`Pool::call_bound`]) for
    /// every worker's answer. `Some` answer when all answered: every env's rows in env order,
    /// a view of the call's slot; `None` when `timeout` passed first: the call stays pending,
    /// so wait again. An error abandons it: the pool then needs a reset.
    pub fn wait(&mut self, timeout: Option<Duration>) -> Result<Option<Received>, PoolError> {
        self.begin_call()?;
        self.collect(timeout)
    }

    /// [`Pool::wait`] within the bound of the call in progress (the send and the wait of
    /// [`Pool::step`] are one call): the receive of every env, in env order.
    fn collect(&mut self, timeout: Option<Duration>) -> Result<Option<Received>, PoolError> {
        let Some(sent) = self.sup.call.sent.take() else {
            return Err(PoolError::State(
                "no step or reset is pending: send_step() or send_reset() first".into(),
            ));
        };
        let until = timeout.map(|t| Instant::now() + t);
        self.sup.call.wait_now = self.sup.expected_wait(sent.at);
        let every = RecvWant::exactly(self.sup.cfg.num_envs);
        let got = self.receive(every, until, true);
        self.sup.call.wait_now = None;
        match got {
            Ok(None) => {
                self.sup.call.sent = Some(sent);
                Ok(None)
            }
            Ok(Some(got)) => {
                // How long the workers took (by their own stamps, not by when this side saw
                // the answers: a late look must not lengthen the next wait).
                let took = self.sup.call.ready_ns.saturating_sub(sent.at_ns);
                self.sup.call.expected_answer = Some(Duration::from_nanos(took));
                let slot = got.slot().unwrap_or(self.sup.next_slot);
                self.sup.next_slot = (slot + 1) % self.sup.cfg.batch_slots;
                self.sup.recycling.replaced_envs.clone_from(&got.recycled);
                Ok(Some(got))
            }
            Err(e) => {
                // The workers that answered are idle, the others are drained by the reset.
                self.sup.failures.must_reset = true;
                Err(e)
            }
        }
    }

    /// Copy a result's rows out: every row's record into `out` (cleared first) and, with
    /// `obs_out` (`rows x obs_bytes`, row-major), the observations; a view's from its slot
    /// (final observations too), gathered rows from their copies. The Rust API's copying form
    /// of the rows a binding reads in place.
    pub fn read_rows(
        &self,
        a: &Received,
        obs_out: Option<&mut [u8]>,
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        let n = a.env_ids.len();
        let ob = self.sup.spec.obs_bytes();
        if let Some(o) = &obs_out
            && o.len() != n * ob
        {
            return Err(PoolError::BadBuffer {
                what: "observation buffer",
                expected: n * ob,
                got: o.len(),
            });
        }
        out.clear();
        let n_info = self.sup.spec.info_names.len();
        let Some((slot, first)) = a.view else {
            for (&e, r) in a.env_ids.iter().zip(&a.records) {
                out.push(e, r, n_info, None);
            }
            if let Some(o) = obs_out {
                o.copy_from_slice(&a.obs);
            }
            if let SlotExtras::Rows(x) = &a.extras {
                out.extras = x.iter().map(|(r, b)| (a.env_ids[*r], b.clone())).collect();
            }
            return Ok(());
        };
        let rows = self.sup.rows_of(slot)?;
        let envs = first..first + n;
        // SAFETY: no call runs (`&self`), so no worker writes the slot; only read here.
        let (obs, fin) = unsafe { (rows.obs_rows(envs.clone()), rows.final_rows(envs.clone())) };
        if let Some(o) = obs_out {
            o.copy_from_slice(obs);
        }
        for (r, e) in envs.clone().enumerate() {
            let f = (!fin.is_empty()).then(|| &fin[r * ob..(r + 1) * ob]);
            out.push(e, &rows.read(e), n_info, f);
        }
        out.extras = match &a.extras {
            SlotExtras::None => Vec::new(),
            SlotExtras::Rows(x) => x.iter().map(|(r, b)| (first + r, b.clone())).collect(),
            &SlotExtras::Uniform(size) => {
                let xb = self.sup.spec.extra_bytes;
                // SAFETY: as above.
                let x = unsafe { rows.extra_rows(envs.clone()) };
                (envs.enumerate())
                    .map(|(r, e)| (e, x[r * xb..r * xb + size.min(xb)].to_vec()))
                    .collect()
            }
        };
        Ok(())
    }

    /// The rows of batch slot `slot` (to read them in place, or to view them from another
    /// language); `None` once closed or for a slot that does not exist.
    pub fn slot_rows(&self, slot: usize) -> Option<SlotRows> {
        self.sup.rows_of(slot).ok()
    }

    /// The layout of a batch slot.
    pub fn slot_layout(&self) -> SlotLayout {
        self.sup.slot_layout
    }

    /// Make the next whole-batch call write slot `slot` (then the turns go on from there): a
    /// caller that keeps the observations of some slots without copying them (all but one of
    /// the [`crate::PoolConfig::batch_slots`]) steers the workers to a slot it no longer holds.
    pub fn select_slot(&mut self, slot: usize) -> Result<(), PoolError> {
        let slots = self.sup.cfg.batch_slots;
        if slot >= slots {
            return Err(PoolError::Config(format!(
                "slot {slot} does not exist: the pool has {slots} batch slots (0..{slots})"
            )));
        }
        self.sup.next_slot = slot;
        Ok(())
    }

    /// Slots of the shared batch buffer ([`crate::PoolConfig::batch_slots`]).
    pub fn batch_slots(&self) -> usize {
        self.sup.cfg.batch_slots
    }

    /// The observations of batch slot `slot` (`num_envs x obs_bytes`, env-major, 64-byte
    /// aligned): valid as [`Pool::send_step`] says.
    pub fn shared_obs(&self, slot: usize) -> &[u8] {
        match self.sup.rows_of(slot) {
            // SAFETY: workers write a slot only during a call, which needs `&mut self`: none
            // runs while this borrow lives.
            Ok(w) => unsafe { w.obs_rows(0..self.sup.cfg.num_envs) },
            Err(_) => &[],
        }
    }

    /// The shared batch buffer itself: slot `s` starts at byte `s * slot_layout().bytes()`.
    /// Holding this `Arc` keeps the mapping valid even after [`Pool::close`] (e.g. as the base
    /// object of numpy views); `None` after close.
    pub fn shared_buffer(&self) -> Option<std::sync::Arc<rogue_gym_ipc::SharedBuffer>> {
        self.sup.batch.clone()
    }
}

impl super::Supervisor {
    /// Note a whole-batch call sent to every env, into the next slot, which it returns: each
    /// worker block one run of the lane, in block order ([`super::async_envs`]); `resets`, a
    /// partial reset's mask.
    pub(super) fn send_whole(&mut self, resets: Option<&[bool]>) -> usize {
        let slot = self.next_slot;
        self.call.ready_ns = 0;
        (self.async_api.envs).send_whole(slot, &self.blocks, &self.slots, resets);
        slot
    }

    /// Send worker `k` its share of the whole-batch call into `slot` with `send` (given where
    /// its envs go; none where the call's answers of all its envs are in already). A failure
    /// leaves the pool needing a reset (some workers may have the command, some not).
    fn send_share(
        &mut self,
        k: usize,
        slot: usize,
        send: impl FnOnce(&mut Self, Target<'_>) -> Result<(), PoolError>,
    ) -> Result<(), PoolError> {
        let r = match self
            .async_api
            .envs
            .whole_targets(self.blocks[k].clone(), slot)
        {
            None => send(self, Target::Slot(slot)),
            Some(t) if t.iter().all(|&w| w == 0) => Ok(()),
            Some(t) => send(self, Target::Each(&t)),
        };
        r.inspect_err(|_| self.failures.must_reset = true)
    }

    /// The rows of slot `slot` (from `slots`, made once: a slot's rows are the same for the
    /// pool's life).
    pub(super) fn rows_of(&self, slot: usize) -> Result<SlotRows, PoolError> {
        self.slots.get(slot).copied().ok_or(PoolError::Closed)
    }

    /// The rows of every slot of the batch buffer, once it is made.
    pub(super) fn make_slot_rows(&mut self) {
        self.slots = match &self.batch {
            // SAFETY: every slot lies inside the mapping, which `self.batch` keeps alive as
            // long as `slots` is kept (both go at close); it is 64-byte aligned (page-aligned
            // mapping, 64-byte slots).
            Some(b) => (0..self.cfg.batch_slots)
                .map(|s| unsafe {
                    self.slot_layout
                        .rows(b.as_ptr().add(s * self.slot_layout.bytes()))
                })
                .collect(),
            None => Vec::new(),
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_send<T: Send>() {}

    #[test]
    fn a_pool_is_send() {
        assert_send::<Pool>();
    }
}
