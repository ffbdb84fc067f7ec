//! EnvPool-style async stepping: `async_reset`, `send` and `recv` of whole worker blocks.

use super::Pool;
use super::stepping::Actions;
use super::workers::SlotState;
use crate::batch::Batch;
use crate::error::PoolError;

impl Pool {
    /// Async: reset every env (as [`Pool::reset`]; outstanding results are discarded); collect
    /// the results with [`Pool::recv`].
    pub fn async_reset(&mut self) -> Result<(), PoolError> {
        self.begin_call()?;
        self.drain()?;
        for k in 0..self.core.slots.len() {
            self.core.send_reset(k, 0)?;
        }
        self.core.must_reset = false;
        Ok(())
    }

    /// Async: send actions to envs. `env_ids` must consist of whole worker blocks
    /// ([`Pool::worker_envs`]), each in order, whose previous result has been received;
    /// `actions[r]` is for `env_ids[r]`.
    pub fn send(&mut self, actions: &[i64], env_ids: &[usize]) -> Result<(), PoolError> {
        self.send_actions(Actions::Indices(actions), env_ids)
    }

    /// [`Pool::send`] with actions of either kind ([`Actions`]).
    pub fn send_actions(
        &mut self,
        actions: Actions<'_>,
        env_ids: &[usize],
    ) -> Result<(), PoolError> {
        self.begin_call()?;
        if self.core.must_reset {
            return Err(PoolError::State(
                "call async_reset() before send() (after creation or after a worker failure)"
                    .into(),
            ));
        }
        self.check_actions(actions, env_ids)?;
        // Split env_ids into whole worker blocks, each in order.
        let mut workers: Vec<(usize, usize)> = Vec::new();
        let mut pos = 0;
        while pos < env_ids.len() {
            let first = env_ids[pos];
            let Some(k) = self.core.blocks.iter().position(|b| b.start == first) else {
                return Err(PoolError::State(format!(
                    "send() env ids must form whole worker blocks, each in order; env {first} does not start a block (blocks: {:?})",
                    self.core.blocks
                )));
            };
            let block = self.core.blocks[k].clone();
            let got = &env_ids[pos..(pos + block.len()).min(env_ids.len())];
            if !got.iter().copied().eq(block.clone()) {
                return Err(PoolError::State(format!(
                    "send() env ids {got:?} do not form worker block {block:?}: give each block's ids in order"
                )));
            }
            let state = &self.core.slots[k].state;
            if !(matches!(state, SlotState::Idle) || state.coming_back_idle())
                || workers.iter().any(|&(w, _)| w == k)
            {
                return Err(PoolError::State(format!(
                    "send() to envs {block:?} whose previous request has not been received yet: recv() first"
                )));
            }
            workers.push((k, pos));
            pos += block.len();
        }
        // Planned replacements happen here, between two commands (see `recycling`).
        for &(k, _) in &workers {
            self.core.recycle_if_due(k)?;
        }
        // Workers replaced while idle may still be coming back.
        self.wait_until(|c| {
            workers
                .iter()
                .all(|&(k, _)| !c.slots[k].state.coming_back_idle())
        })?;
        let ab = self.core.spec.action_bytes;
        for &(k, pos) in &workers {
            let rows = pos..pos + self.core.blocks[k].len();
            self.core.send_step(k, actions.rows(rows, ab), 0)?;
        }
        Ok(())
    }

    /// Async: wait for the next `batch_size` envs (whole blocks, in arrival order) and hand
    /// their blocks over (zero-copy; see [`Block`] for lifetimes).
    pub fn recv(&mut self) -> Result<Batch, PoolError> {
        self.begin_call()?;
        // Blocks per batch: batch_size is num_envs, or a multiple of the (even) block size.
        let want = self.batch_size() * self.core.blocks.len() / self.core.cfg.num_envs;
        let outstanding = self
            .core
            .slots
            .iter()
            .filter(|s| !matches!(s.state, SlotState::Idle) && !s.state.coming_back_idle())
            .count();
        if outstanding < want {
            return Err(PoolError::State(format!(
                "recv() needs {want} outstanding worker blocks but only {outstanding} are: send() actions (or async_reset()) first"
            )));
        }
        self.wait_until(|c| c.ready_order.len() >= want)?;
        let mut blocks = Vec::with_capacity(want);
        for _ in 0..want {
            let Some(k) = self.core.ready_order.pop_front() else {
                break;
            };
            blocks.push(self.core.take_block(k)?);
        }
        Ok(Batch { blocks })
    }
}
