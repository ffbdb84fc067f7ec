//! Sync stepping: reset, partial reset and step, with the observations copied into the
//! caller's buffer or written by the workers straight into the shared batch slots.

use std::ops::Range;

use super::Pool;
use crate::batch::{Batch, BatchOutput, Block};
use crate::error::PoolError;

/// The actions of a step, one per env: indices `0..num_actions`, or `EnvSpec::action_bytes`
/// raw bytes each (envs that decode their own actions, such as hosted gymnasium envs).
#[derive(Debug, Clone, Copy)]
pub enum Actions<'a> {
    /// One index per env.
    Indices(&'a [i64]),
    /// `action_bytes` bytes per env, env after env.
    Bytes(&'a [u8]),
}

impl<'a> Actions<'a> {
    /// The actions of rows `rows` (`action_bytes`: bytes per action, for `Bytes`).
    pub(crate) fn rows(self, rows: Range<usize>, action_bytes: usize) -> Actions<'a> {
        match self {
            Actions::Indices(a) => Actions::Indices(&a[rows]),
            Actions::Bytes(b) => {
                Actions::Bytes(&b[rows.start * action_bytes..rows.end * action_bytes])
            }
        }
    }
}

/// Check that every action is in `0..num_actions`; the error names the env and the value.
pub fn validate_actions(
    actions: &[i64],
    env_ids: impl Iterator<Item = usize>,
    num_actions: usize,
) -> Result<(), PoolError> {
    for (a, env) in actions.iter().zip(env_ids) {
        if *a < 0 || *a as u64 >= num_actions as u64 {
            return Err(PoolError::BadAction {
                env,
                value: *a,
                num_actions,
            });
        }
    }
    Ok(())
}

impl Pool {
    /// Sync reset: start a new episode in every env (episode index 0 at the first reset, then
    /// the next index of each env), write the observations into `obs_out`
    /// (`num_envs x obs_bytes`, env-major) and the per-env arrays into `out`. Results of
    /// outstanding async requests (or of a step interrupted by an error) are discarded.
    pub fn reset(&mut self, obs_out: &mut [u8], out: &mut BatchOutput) -> Result<(), PoolError> {
        self.begin_call()?;
        self.check_obs_buf(obs_out)?;
        self.drain()?;
        for k in 0..self.sup.slots.len() {
            self.sup.send_reset(k, 0)?;
        }
        self.sup.must_reset = false;
        self.gather_all(Some(obs_out), out)
    }

    /// Sync step: `actions[i]` for env `i` (all envs). Writes observations into `obs_out`
    /// (`num_envs x obs_bytes`, env-major; one memcpy per worker block) and per-env arrays into
    /// `out`. See [`AutoresetMode`] for what a step after/at an episode end returns.
    pub fn step(
        &mut self,
        actions: &[i64],
        obs_out: &mut [u8],
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        self.step_actions(Actions::Indices(actions), obs_out, out)
    }

    /// [`Pool::step`] with actions of either kind ([`Actions`]).
    pub fn step_actions(
        &mut self,
        actions: Actions<'_>,
        obs_out: &mut [u8],
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        self.check_obs_buf(obs_out)?;
        self.prepare_sync_step(actions)?;
        self.send_steps(actions, 0)?;
        self.gather_all(Some(obs_out), out)
    }

    /// Send each worker its block of `actions`.
    fn send_steps(&mut self, actions: Actions<'_>, target: u32) -> Result<(), PoolError> {
        let ab = self.sup.spec.action_bytes;
        for k in 0..self.sup.slots.len() {
            let rows = self.sup.env_range(k);
            self.sup.send_step(k, actions.rows(rows, ab), target)?;
        }
        Ok(())
    }

    /// Like [`Pool::reset`], but the workers write the observations straight into the next
    /// slot of the pool's shared batch buffer (no copy at all); returns the slot index for
    /// [`Pool::shared_obs`].
    pub fn reset_shared(&mut self, out: &mut BatchOutput) -> Result<usize, PoolError> {
        // One call, one bound: the collecting half does not start a new call.
        self.send_reset_shared()?;
        self.collect_split(None, out)?
            .ok_or_else(|| PoolError::State("a reset without a timeout timed out".into()))
    }

    /// Partial sync reset (gymnasium's `reset(options={"reset_mask": mask})`), into the next
    /// shared batch slot like [`Pool::reset_shared`]; returns the slot.
    ///
    /// * Envs with `mask[i] == true` start their next scheduled episode (episode index + 1, its
    ///   seed from the schedule), exactly as a full reset would start it for them, so
    ///   trajectories stay independent of the worker count.
    /// * Envs with `mask[i] == false` keep their state (an episode that ended in NEXT_STEP mode
    ///   is still autoreset by the next step); their current observation is re-written into
    ///   the slot by the worker ([`crate::Env::observe`]), and their row in `out` describes
    ///   their current episode with reward 0 and no flags.
    ///
    /// Needs a full reset first (after creation, [`Pool::set_seeds`] or a worker failure
    /// under [`FailurePolicy::Raise`]) and no outstanding async requests (sync only; there is
    /// no async partial reset). A worker restarted during the call resets all its envs (they
    /// report `restarted`).
    pub fn reset_envs(&mut self, mask: &[bool], out: &mut BatchOutput) -> Result<usize, PoolError> {
        let slot = self.sup.next_slot;
        self.reset_masked(mask, slot as u32 + 1, None, out)?;
        self.sup.next_slot = (slot + 1) % self.sup.cfg.batch_slots;
        Ok(slot)
    }

    /// [`Pool::reset_envs`], with the observations copied into `obs_out` (`num_envs x
    /// obs_bytes`) like [`Pool::reset`].
    pub fn reset_envs_into(
        &mut self,
        mask: &[bool],
        obs_out: &mut [u8],
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        self.check_obs_buf(obs_out)?;
        self.reset_masked(mask, 0, Some(obs_out), out)
    }

    fn reset_masked(
        &mut self,
        mask: &[bool],
        target: u32,
        obs_out: Option<&mut [u8]>,
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        self.begin_call()?;
        if mask.len() != self.sup.cfg.num_envs {
            return Err(PoolError::BadBuffer {
                what: "reset mask",
                expected: self.sup.cfg.num_envs,
                got: mask.len(),
            });
        }
        if self.sup.must_reset {
            return Err(PoolError::State(
                "a partial reset needs every env started: call a full reset() first (after creation, set_seeds or a worker failure)".into(),
            ));
        }
        self.all_idle()?;
        for k in 0..self.sup.slots.len() {
            self.sup.send_reset_masked(k, target, Some(mask))?;
        }
        self.gather_all(obs_out, out)
    }

    /// Like [`Pool::step`], but the workers write the observations straight into the next
    /// slot of the pool's shared batch buffer (zero-copy sync step); returns the slot index
    /// for [`Pool::shared_obs`]. Slots take turns ([`crate::PoolConfig::batch_slots`] of
    /// them, two by default): the observations of slot `s` stay unchanged until the call that
    /// writes `s` again, at the earliest the second `*_shared` call after the one that
    /// returned `s`. [`Pool::select_slot`] names the slot the next call writes.
    pub fn step_shared(
        &mut self,
        actions: &[i64],
        out: &mut BatchOutput,
    ) -> Result<usize, PoolError> {
        self.step_shared_actions(Actions::Indices(actions), out)
    }

    /// [`Pool::step_shared`] with actions of either kind ([`Actions`]).
    pub fn step_shared_actions(
        &mut self,
        actions: Actions<'_>,
        out: &mut BatchOutput,
    ) -> Result<usize, PoolError> {
        self.prepare_sync_step(actions)?;
        let slot = self.sup.next_slot;
        self.send_steps(actions, slot as u32 + 1)?;
        self.gather_all(None, out)?;
        self.sup.next_slot = (slot + 1) % self.sup.cfg.batch_slots;
        Ok(slot)
    }

    /// The first half of [`Pool::step_shared_actions`] (gymnasium's `step_async`): check the
    /// actions and send each worker its block, to be written into the next shared slot, which
    /// it returns; the workers step while the caller does something else. Collect the answers
    /// with [`Pool::wait_shared`]; a sync call in between fails (a reset abandons the step).
    pub fn send_step_shared(&mut self, actions: Actions<'_>) -> Result<usize, PoolError> {
        self.prepare_sync_step(actions)?;
        let slot = self.sup.next_slot;
        self.send_steps(actions, slot as u32 + 1)?;
        self.sup.split = Some(slot);
        Ok(slot)
    }

    /// The first half of [`Pool::reset_shared`] (gymnasium's `reset_async`); collect the
    /// answers with [`Pool::wait_shared`].
    pub fn send_reset_shared(&mut self) -> Result<usize, PoolError> {
        self.begin_call()?;
        self.drain()?;
        let slot = self.sup.next_slot;
        for k in 0..self.sup.slots.len() {
            self.sup.send_reset(k, slot as u32 + 1)?;
        }
        self.sup.must_reset = false;
        self.sup.split = Some(slot);
        Ok(slot)
    }

    /// The second half of a step or reset sent by [`Pool::send_step_shared`] or
    /// [`Pool::send_reset_shared`]: wait for every worker's answer, at most `timeout` (and
    /// always within the call's bound, [`Pool::call_bound`]). `Some(slot)` with `out` filled
    /// when all answered; `None` when `timeout` passed first: the request stays pending, so
    /// wait again. An error abandons it (a reset recovers).
    pub fn wait_shared(
        &mut self,
        timeout: Option<std::time::Duration>,
        out: &mut BatchOutput,
    ) -> Result<Option<usize>, PoolError> {
        self.begin_call()?;
        self.collect_split(timeout, out)
    }

    /// The body of [`Pool::wait_shared`], within the current call's bound.
    fn collect_split(
        &mut self,
        timeout: Option<std::time::Duration>,
        out: &mut BatchOutput,
    ) -> Result<Option<usize>, PoolError> {
        let Some(slot) = self.sup.split else {
            return Err(PoolError::State(
                "no step or reset is pending: send_step_shared() or send_reset_shared() first"
                    .into(),
            ));
        };
        let until = timeout.map(|t| std::time::Instant::now() + t);
        let workers = self.sup.slots.len();
        match self.wait_until_or(|c| c.ready_order.len() == workers, until) {
            Ok(false) => return Ok(None),
            Ok(true) => {}
            Err(e) => {
                self.sup.split = None;
                return Err(e);
            }
        }
        self.sup.split = None;
        self.gather_all(None, out)?;
        self.sup.next_slot = (slot + 1) % self.sup.cfg.batch_slots;
        Ok(Some(slot))
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
    /// 64-byte aligned). See [`Pool::step_shared`] for when they are valid.
    pub fn shared_obs(&self, slot: usize) -> &[u8] {
        let n = self.sup.cfg.num_envs * self.sup.spec.obs_bytes();
        match &self.sup.batch {
            // SAFETY: the slot lies inside the mapping. Workers write a slot only during a
            // `*_shared` call, which needs `&mut self`: none runs while this borrow lives.
            Some(b) if slot < self.sup.cfg.batch_slots => unsafe {
                std::slice::from_raw_parts(b.as_ptr().add(slot * self.sup.slot_bytes), n)
            },
            _ => &[],
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
        self.sup.slot_bytes
    }

    /// Raw pointer to shared batch slot `slot` (for zero-copy views in other languages; keep
    /// [`Pool::shared_buffer`] alive with the view). Null after `close`.
    pub fn shared_obs_ptr(&self, slot: usize) -> *const u8 {
        match &self.sup.batch {
            Some(b) if slot < self.sup.cfg.batch_slots => {
                // SAFETY: the offset stays inside the mapping.
                unsafe { b.as_ptr().add(slot * self.sup.slot_bytes) }
            }
            _ => std::ptr::null(),
        }
    }

    /// Checks before a sync step: the pool is open and started, there is one valid action
    /// per env, and no async request is outstanding.
    fn prepare_sync_step(&mut self, actions: Actions<'_>) -> Result<(), PoolError> {
        self.begin_call()?;
        let all: Vec<usize> = (0..self.sup.cfg.num_envs).collect();
        self.check_actions(actions, &all)?;
        if self.sup.must_reset {
            return Err(PoolError::State(
                "call reset() before step() (after creation or after a worker failure)".into(),
            ));
        }
        self.all_idle()?;
        // Planned replacements happen here, between two commands (see `recycling`).
        let mut replaced = false;
        for k in 0..self.sup.slots.len() {
            replaced |= self.sup.recycle_if_due(k)?;
        }
        if replaced {
            self.all_idle()?;
        }
        Ok(())
    }

    fn gather_all(
        &mut self,
        mut obs_out: Option<&mut [u8]>,
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        // Copy each block as soon as it arrives, overlapping with the other workers' steps.
        let w = self.sup.slots.len();
        let ob = self.sup.spec.obs_bytes();
        let mut blocks: Vec<Option<Block>> = (0..w).map(|_| None).collect();
        let mut got = 0;
        while got < w {
            self.wait_until(|c| !c.ready_order.is_empty())?;
            while let Some(k) = self.sup.ready_order.pop_front() {
                let b = self.sup.take_block(k)?;
                if let Some(o) = obs_out.as_deref_mut() {
                    let envs = b.env_ids();
                    o[envs.start * ob..envs.end * ob].copy_from_slice(b.obs());
                }
                blocks[k] = Some(b);
                got += 1;
            }
        }
        out.clear();
        let n_info = self.sup.spec.info_names.len();
        let batch = Batch {
            blocks: blocks.into_iter().flatten().collect(),
        };
        batch.fill_append(n_info, out);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_send<T: Send>() {}

    #[test]
    fn actions_are_validated_with_env_and_value() {
        assert!(validate_actions(&[0, 10, 5], 0..3, 11).is_ok());
        let e = validate_actions(&[0, 11], 4..6, 11).unwrap_err();
        assert_eq!(
            e.to_string(),
            "env 5: action 11 is out of range; valid actions are 0 to 10 (range(11))"
        );
        assert!(matches!(
            validate_actions(&[-1], 0..1, 11),
            Err(PoolError::BadAction {
                env: 0,
                value: -1,
                ..
            })
        ));
    }

    #[test]
    fn pool_and_block_are_send() {
        assert_send::<Pool>();
        assert_send::<Block>();
        assert_send::<Batch>();
    }
}
