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
        self.check_usable()?;
        self.drain()?;
        for k in 0..self.core.slots.len() {
            self.core.send_reset(k, 0)?;
        }
        self.core.must_reset = false;
        Ok(())
    }

    /// Async: send actions to envs. `env_ids` must consist of whole worker blocks, each in
    /// order (`k*epw .. (k+1)*epw`), whose previous result has been received; `actions[r]` is
    /// for `env_ids[r]`.
    pub fn send(&mut self, actions: &[i64], env_ids: &[usize]) -> Result<(), PoolError> {
        self.send_actions(Actions::Indices(actions), env_ids)
    }

    /// [`Pool::send`] with actions of either kind ([`Actions`]).
    pub fn send_actions(
        &mut self,
        actions: Actions<'_>,
        env_ids: &[usize],
    ) -> Result<(), PoolError> {
        self.check_usable()?;
        if self.core.must_reset {
            return Err(PoolError::State(
                "call async_reset() before send() (after creation or after a worker failure)"
                    .into(),
            ));
        }
        self.check_actions(actions, env_ids)?;
        let epw = self.core.epw;
        if !env_ids.len().is_multiple_of(epw) {
            return Err(PoolError::State(format!(
                "send() got {} env ids; they must form whole worker blocks of {epw} envs",
                env_ids.len()
            )));
        }
        let mut workers = Vec::with_capacity(env_ids.len() / epw);
        for chunk in env_ids.chunks(epw) {
            let k = chunk[0] / epw;
            if !chunk[0].is_multiple_of(epw)
                || k >= self.core.slots.len()
                || chunk.iter().enumerate().any(|(j, &e)| e != k * epw + j)
            {
                return Err(PoolError::State(format!(
                    "send() env ids {chunk:?} do not form a worker block: give each block's ids in order, k*{epw}..(k+1)*{epw}"
                )));
            }
            if !matches!(self.core.slots[k].state, SlotState::Idle) || workers.contains(&k) {
                return Err(PoolError::State(format!(
                    "send() to envs {}..{} whose previous request has not been received yet: recv() first",
                    k * epw,
                    (k + 1) * epw
                )));
            }
            workers.push(k);
        }
        let ab = self.core.spec.action_bytes;
        for (r, &k) in workers.iter().enumerate() {
            self.core
                .send_step(k, actions.rows(r * epw..(r + 1) * epw, ab), 0)?;
        }
        Ok(())
    }

    /// Async: wait for the next `batch_size` envs (whole blocks, in arrival order) and hand
    /// their blocks over (zero-copy; see [`Block`] for lifetimes).
    pub fn recv(&mut self) -> Result<Batch, PoolError> {
        self.check_usable()?;
        let want = self.batch_size() / self.core.epw;
        let outstanding = self
            .core
            .slots
            .iter()
            .filter(|s| !matches!(s.state, SlotState::Idle))
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
