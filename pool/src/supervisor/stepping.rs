//! Sync stepping: reset, partial reset and step, every per-env output written by the workers
//! in place into a shared batch slot (copied out only by the Rust API's copying forms).

use super::Pool;
use super::actions::{Actions, validate_actions};
use super::slot_answers::SlotCollect;
use crate::batch::{BatchOutput, SlotAnswer, SlotExtras};
use crate::error::PoolError;
use crate::wire::slot_layout::{RowWriter, SlotLayout};

impl Pool {
    /// Sync reset: start a new episode in every env (episode index 0 at the first reset, then
    /// the next index of each env), copy the observations into `obs_out` (`num_envs x
    /// obs_bytes`, env-major) and the per-env values into `out`: [`Pool::reset_slot`], read
    /// back env by env (a convenience of the Rust API; the Python front reads the slot in
    /// place). Results of outstanding async requests (or of a step interrupted by an error)
    /// are discarded.
    pub fn reset(&mut self, obs_out: &mut [u8], out: &mut BatchOutput) -> Result<(), PoolError> {
        self.check_obs_buf(obs_out)?;
        let a = self.reset_slot()?;
        self.read_slot(&a, Some(obs_out), out);
        Ok(())
    }

    /// Sync step: `actions[i]` for env `i` (all envs: indices, `&[i64]`, or any
    /// [`Actions`]), copied out like [`Pool::reset`]. See [`AutoresetMode`] for what a step
    /// after/at an episode end returns.
    pub fn step<'a>(
        &mut self,
        actions: impl Into<Actions<'a>>,
        obs_out: &mut [u8],
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        let actions = actions.into();
        self.check_obs_buf(obs_out)?;
        let a = self.step_slot(actions)?;
        self.read_slot(&a, Some(obs_out), out);
        Ok(())
    }

    /// Send each worker its block of `actions`, to be answered into slot `target - 1`.
    fn send_steps(&mut self, actions: Actions<'_>, target: u32) -> Result<(), PoolError> {
        let ab = self.sup.spec.action_bytes;
        for k in 0..self.sup.workers.len() {
            let rows = self.sup.env_range(k);
            self.sup.send_step(k, actions.rows(rows, ab), target)?;
        }
        Ok(())
    }

    /// Like [`Pool::reset`], read back into `out`; returns the slot the workers wrote.
    pub fn reset_shared(&mut self, out: &mut BatchOutput) -> Result<usize, PoolError> {
        let a = self.reset_slot()?;
        self.read_slot(&a, None, out);
        Ok(a.slot)
    }

    /// A sync reset whose every per-env output the workers write in place, into the next slot
    /// of the shared batch buffer ([`crate::wire::slot_layout`]): nothing is copied or
    /// gathered; [`SlotAnswer`] says which slot and what else to read there.
    pub fn reset_slot(&mut self) -> Result<SlotAnswer, PoolError> {
        // One call, one bound: the collecting half does not start a new call.
        self.send_reset_shared()?;
        self.collect_split(None)?
            .ok_or_else(|| PoolError::State("a reset without a timeout timed out".into()))
    }

    /// [`Pool::reset_envs_slot`], read back into `out`; returns the slot.
    pub fn reset_envs(&mut self, mask: &[bool], out: &mut BatchOutput) -> Result<usize, PoolError> {
        let a = self.reset_envs_slot(mask)?;
        self.read_slot(&a, None, out);
        Ok(a.slot)
    }

    /// Partial sync reset (gymnasium's `reset(options={"reset_mask": mask})`), in place into
    /// the next shared batch slot like [`Pool::reset_slot`].
    ///
    /// * Envs with `mask[i] == true` start their next scheduled episode (episode index + 1, its
    ///   seed from the schedule), exactly as a full reset would start it for them, so
    ///   trajectories stay independent of the worker count.
    /// * Envs with `mask[i] == false` keep their state (an episode that ended in NEXT_STEP mode
    ///   is still autoreset by the next step); their current observation is re-written into
    ///   the slot by the worker ([`crate::Env::observe`]), and their row describes their
    ///   current episode with reward 0 and no flags.
    ///
    /// Needs a full reset first (after creation, [`Pool::set_seeds`] or a worker failure
    /// under [`FailurePolicy::Raise`]) and no outstanding async requests (sync only; there is
    /// no async partial reset). A worker restarted during the call resets all its envs (they
    /// report `restarted`).
    pub fn reset_envs_slot(&mut self, mask: &[bool]) -> Result<SlotAnswer, PoolError> {
        self.begin_call()?;
        if mask.len() != self.sup.cfg.num_envs {
            return Err(PoolError::BadBuffer {
                what: "reset mask",
                expected: self.sup.cfg.num_envs,
                got: mask.len(),
            });
        }
        if self.sup.failures.must_reset {
            return Err(PoolError::State(
                "a partial reset needs every env started: call a full reset() first (after creation, set_seeds or a worker failure)".into(),
            ));
        }
        self.all_idle()?;
        let slot = self.sup.next_slot;
        for k in 0..self.sup.workers.len() {
            self.sup.send_reset_masked(k, slot as u32 + 1, Some(mask))?;
        }
        self.sup.call.split = Some(slot);
        self.sup.call.split_sent = std::time::Instant::now();
        self.sup.call.split_sent_ns = rogue_gym_ipc::monotonic_ns();
        self.sup.call.collecting = None;
        self.collect_split(None)?
            .ok_or_else(|| PoolError::State("a partial reset timed out".into()))
    }

    /// [`Pool::reset_envs`], copied out into `obs_out` (`num_envs x obs_bytes`) and `out`
    /// like [`Pool::reset`].
    pub fn reset_envs_into(
        &mut self,
        mask: &[bool],
        obs_out: &mut [u8],
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        self.check_obs_buf(obs_out)?;
        let a = self.reset_envs_slot(mask)?;
        self.read_slot(&a, Some(obs_out), out);
        Ok(())
    }

    /// Like [`Pool::step`], read back into `out`; returns the slot the workers wrote (its
    /// observations: [`Pool::shared_obs`]).
    pub fn step_shared<'a>(
        &mut self,
        actions: impl Into<Actions<'a>>,
        out: &mut BatchOutput,
    ) -> Result<usize, PoolError> {
        let a = self.step_slot(actions)?;
        self.read_slot(&a, None, out);
        Ok(a.slot)
    }

    /// A sync step whose every per-env output (observations, rewards, flags, episode books,
    /// info values, final observations, extra info) the workers write in place, into the next
    /// slot of the shared batch buffer: the caller's work is one command per worker and one
    /// answer per worker, whatever the number of envs. Slots take turns
    /// ([`crate::PoolConfig::batch_slots`] of them, two by default): slot `s` stays unchanged
    /// until the call that writes `s` again, at the earliest the second slot call after the
    /// one that returned `s`. [`Pool::select_slot`] names the slot the next call writes.
    pub fn step_slot<'a>(
        &mut self,
        actions: impl Into<Actions<'a>>,
    ) -> Result<SlotAnswer, PoolError> {
        self.send_step_shared(actions)?;
        self.collect_split(None)?
            .ok_or_else(|| PoolError::State("a step without a timeout timed out".into()))
    }

    /// The first half of [`Pool::step_slot`] (gymnasium's `step_async`): check the actions
    /// and send each worker its block, to be written into the next shared slot, which it
    /// returns; the workers step while the caller does something else. Collect the answers
    /// with [`Pool::wait_shared`]; a sync call in between fails (a reset abandons the step).
    pub fn send_step_shared<'a>(
        &mut self,
        actions: impl Into<Actions<'a>>,
    ) -> Result<usize, PoolError> {
        let actions = actions.into();
        self.prepare_sync_step(actions)?;
        let slot = self.sup.next_slot;
        self.send_steps(actions, slot as u32 + 1)?;
        self.sup.call.split = Some(slot);
        self.sup.call.split_sent = std::time::Instant::now();
        self.sup.call.split_sent_ns = rogue_gym_ipc::monotonic_ns();
        self.sup.call.collecting = None;
        Ok(slot)
    }

    /// The first half of [`Pool::reset_slot`] (gymnasium's `reset_async`); collect the
    /// answers with [`Pool::wait_shared`].
    pub fn send_reset_shared(&mut self) -> Result<usize, PoolError> {
        self.begin_call()?;
        self.drain()?;
        let slot = self.sup.next_slot;
        for k in 0..self.sup.workers.len() {
            self.sup.send_reset(k, slot as u32 + 1)?;
        }
        self.sup.failures.must_reset = false;
        self.sup.call.split = Some(slot);
        self.sup.call.split_sent = std::time::Instant::now();
        self.sup.call.split_sent_ns = rogue_gym_ipc::monotonic_ns();
        self.sup.call.collecting = None;
        Ok(slot)
    }

    /// The second half of a step or reset sent by [`Pool::send_step_shared`] or
    /// [`Pool::send_reset_shared`]: wait for every worker's answer, at most `timeout` (and
    /// always within the call's bound, [`Pool::call_bound`]). `Some` answer when all
    /// answered; `None` when `timeout` passed first: the request stays pending, so wait
    /// again. An error abandons it (a reset recovers).
    pub fn wait_shared(
        &mut self,
        timeout: Option<std::time::Duration>,
    ) -> Result<Option<SlotAnswer>, PoolError> {
        self.begin_call()?;
        self.collect_split(timeout)
    }

    /// The body of [`Pool::wait_shared`], within the current call's bound.
    fn collect_split(
        &mut self,
        timeout: Option<std::time::Duration>,
    ) -> Result<Option<SlotAnswer>, PoolError> {
        let Some(slot) = self.sup.call.split else {
            return Err(PoolError::State(
                "no step or reset is pending: send_step_shared() or send_reset_shared() first"
                    .into(),
            ));
        };
        let until = timeout.map(|t| std::time::Instant::now() + t);
        let workers = self.sup.workers.len();
        let mut acc = self
            .sup
            .call
            .collecting
            .take()
            .unwrap_or_else(|| SlotCollect::new(slot));
        self.sup.call.wait_now = self.sup.expected_wait();
        let mut polls = 0;
        let done = self.wait_for(
            |c| {
                polls += 1;
                c.take_slot_answers(&mut acc)?;
                Ok(acc.answered == workers)
            },
            until,
        );
        self.sup.call.wait_now = None;
        if matches!(done, Ok(true)) && polls > 1 {
            // Waited for: how long the workers took (by their own stamps, not by when this side
            // saw the answers: a late look must not lengthen the next wait), for the next wait.
            let took = acc.ready_ns.saturating_sub(self.sup.call.split_sent_ns);
            self.sup.call.expected_answer = Some(std::time::Duration::from_nanos(took));
        }
        match done {
            Ok(false) => {
                self.sup.call.collecting = Some(acc);
                return Ok(None);
            }
            Ok(true) => {}
            Err(e) => {
                self.sup.call.split = None;
                return Err(e);
            }
        }
        self.sup.call.split = None;
        self.sup.next_slot = (slot + 1) % self.sup.cfg.batch_slots;
        Ok(Some(acc.answer))
    }

    /// Read a slot's rows back into `out` (and its observations into `obs_out`), env by env:
    /// the Rust API's copying forms.
    fn read_slot(&self, a: &SlotAnswer, obs_out: Option<&mut [u8]>, out: &mut BatchOutput) {
        out.clear();
        let n = self.sup.cfg.num_envs;
        let n_info = self.sup.spec.info_names.len();
        let ob = self.sup.spec.obs_bytes();
        let Some(w) = self.slot_writer(a.slot) else {
            return;
        };
        // SAFETY: the slot is not being written (no call runs: `&self`); only read here.
        let (obs, fin) = unsafe { (w.obs_rows(0..n), w.final_rows(0..n)) };
        if let Some(o) = obs_out {
            o.copy_from_slice(obs);
        }
        for i in 0..n {
            let r = w.read(i);
            let f = (!fin.is_empty()).then(|| &fin[i * ob..(i + 1) * ob]);
            out.push(i, &r, n_info, f);
        }
        if let SlotExtras::Rows(rows) = &a.extras {
            out.extras = rows.clone();
        } else if let SlotExtras::Uniform(size) = a.extras {
            let xb = self.sup.spec.extra_bytes;
            // SAFETY: as above.
            let x = unsafe { w.extra_rows(0..n) };
            out.extras = (0..n)
                .map(|i| (i, x[i * xb..i * xb + size].to_vec()))
                .collect();
        }
    }

    /// A writer (and reader) of slot `slot`'s rows; `None` once closed or for a slot that
    /// does not exist.
    pub fn slot_writer(&self, slot: usize) -> Option<RowWriter> {
        self.sup.writer_of(slot).ok()
    }

    /// The layout of a shared batch slot.
    pub fn slot_layout(&self) -> SlotLayout {
        self.sup.slot_layout
    }

    /// Make the next `*_shared` call write slot `slot` (then the turns go on from there): a
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

    /// The observations of shared batch slot `slot` (`num_envs x obs_bytes`, env-major,
    /// 64-byte aligned). See [`Pool::step_slot`] for when they are valid.
    pub fn shared_obs(&self, slot: usize) -> &[u8] {
        let n = self.sup.cfg.num_envs;
        match self.slot_writer(slot) {
            // SAFETY: workers write a slot only during a slot call, which needs `&mut self`:
            // none runs while this borrow lives.
            Some(w) => unsafe { w.obs_rows(0..n) },
            None => &[],
        }
    }

    /// The shared batch buffer itself: slot `s` starts at byte `s * shared_slot_bytes()`.
    /// Holding this `Arc` keeps the mapping valid even after [`Pool::close`] (e.g. as the base
    /// object of numpy views); `None` after close.
    pub fn shared_buffer(&self) -> Option<std::sync::Arc<rogue_gym_ipc::SharedBuffer>> {
        self.sup.batch.clone()
    }

    /// Distance in bytes between two shared batch slots.
    pub fn shared_slot_bytes(&self) -> usize {
        self.sup.slot_layout.bytes()
    }

    /// Raw pointer to shared batch slot `slot` (for zero-copy views in other languages; keep
    /// [`Pool::shared_buffer`] alive with the view). Null after `close`.
    pub fn shared_obs_ptr(&self, slot: usize) -> *const u8 {
        match &self.sup.batch {
            Some(b) if slot < self.sup.cfg.batch_slots => {
                // SAFETY: the offset stays inside the mapping.
                unsafe { b.as_ptr().add(slot * self.sup.slot_layout.bytes()) }
            }
            _ => std::ptr::null(),
        }
    }

    /// Check one action per env of `env_ids` (indices in range, or the right byte count).
    pub(super) fn check_actions(
        &self,
        actions: Actions<'_>,
        env_ids: &[usize],
    ) -> Result<(), PoolError> {
        self.check_action_rows(actions, env_ids.len(), |r| env_ids[r])
    }

    /// Check one action per env of the pool.
    fn check_all_actions(&self, actions: Actions<'_>) -> Result<(), PoolError> {
        self.check_action_rows(actions, self.sup.cfg.num_envs, |r| r)
    }

    /// Check `rows` actions, row `r` for env `env_of(r)`.
    fn check_action_rows(
        &self,
        actions: Actions<'_>,
        rows: usize,
        env_of: impl Fn(usize) -> usize,
    ) -> Result<(), PoolError> {
        let spec = &self.sup.spec;
        match actions {
            Actions::Indices(a) if spec.action_bytes == 0 => {
                if a.len() != rows {
                    return Err(PoolError::BadActionsLength {
                        expected: rows,
                        got: a.len(),
                    });
                }
                validate_actions(a, (0..rows).map(env_of), spec.num_actions)
            }
            Actions::Bytes(b) if spec.action_bytes > 0 => {
                if b.len() != rows * spec.action_bytes {
                    return Err(PoolError::BadBuffer {
                        what: "action bytes",
                        expected: rows * spec.action_bytes,
                        got: b.len(),
                    });
                }
                Ok(())
            }
            Actions::Indices(_) => Err(PoolError::Config(format!(
                "this env takes actions as {} raw bytes each, not indices",
                spec.action_bytes
            ))),
            Actions::Bytes(_) => Err(PoolError::Config(format!(
                "this env takes action indices 0..{}, not raw bytes",
                spec.num_actions
            ))),
        }
    }

    /// Checks before a sync step: the pool is open and started, there is one valid action
    /// per env, and no async request is outstanding.
    fn prepare_sync_step(&mut self, actions: Actions<'_>) -> Result<(), PoolError> {
        self.begin_call()?;
        self.check_all_actions(actions)?;
        if self.sup.failures.must_reset {
            return Err(PoolError::State(
                "call reset() before step() (after creation or after a worker failure)".into(),
            ));
        }
        self.all_idle()?;
        // Planned replacements happen here, between two commands (see `recycling`).
        let mut replaced = false;
        for k in 0..self.sup.workers.len() {
            replaced |= self.sup.recycle_if_due(k)?;
        }
        if replaced {
            self.all_idle()?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_send<T: Send>() {}

    #[test]
    fn pool_and_block_are_send() {
        use crate::batch::Block;
        assert_send::<Pool>();
        assert_send::<Block>();
    }
}
