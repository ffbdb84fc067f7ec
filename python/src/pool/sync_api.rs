//! The whole-batch API (gymnasium's `step`/`reset` and their split halves): every env at once,
//! observations straight into the next shared batch slot, results as [`SyncResult`]s.

use numpy::ndarray::ArrayView1;
use numpy::{PyArray1, PyReadonlyArray1, PyUntypedArray};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyList;
use rogue_gym_pool::SeedSchedule;

use super::PyPool;
use super::results::SyncResult;
use crate::gil::lock_gil_free;
use crate::holders::SharedBatchHolder;
use crate::settings;

#[pymethods]
impl PyPool {
    /// A sync step of every env: `actions` (int64, one per env, range-checked here; or raw
    /// uint8 bytes for hosted envs whose actions travel so), observations into the next shared
    /// batch slot, (SAME_STEP) final observations into `final_out`. Returns `(slot, summary,
    /// extras)`; the slot's column buffer holds the per-env values (rewards as float64, flags
    /// as bool, info values as int64 and bool).
    #[pyo3(signature = (actions, final_out = None))]
    fn step<'py>(
        &self,
        py: Python<'py>,
        actions: &Bound<'_, PyAny>,
        final_out: Option<&Bound<'_, PyUntypedArray>>,
    ) -> PyResult<SyncResult<'py>> {
        let acts = self.owned_actions(actions, self.num_envs)?;
        let slot = self.with_pool(py, move |p, out| {
            p.step_shared_actions(acts.as_actions(), out)
        })?;
        self.sync_result(py, slot, final_out)
    }

    /// The first half of a sync step (gymnasium's `step_async`): check `actions` and send
    /// them; the workers step meanwhile. Returns the slot they write. Collect with `wait`.
    fn step_send(&self, py: Python<'_>, actions: &Bound<'_, PyAny>) -> PyResult<usize> {
        let acts = self.owned_actions(actions, self.num_envs)?;
        self.with_pool(py, move |p, _| p.send_step_shared(acts.as_actions()))
    }

    /// The first half of a full reset (gymnasium's `reset_async`); returns the slot.
    fn reset_send(&self, py: Python<'_>) -> PyResult<usize> {
        self.with_pool(py, |p, _| p.send_reset_shared())
    }

    /// The second half of `step_send`/`reset_send`: wait at most `timeout` seconds (`None`:
    /// the call's own bound) for every worker; the result as `step` returns it, or `None` when
    /// `timeout` passed first (the request stays pending: wait again).
    #[pyo3(signature = (timeout = None, final_out = None))]
    fn wait<'py>(
        &self,
        py: Python<'py>,
        timeout: Option<f64>,
        final_out: Option<&Bound<'_, PyUntypedArray>>,
    ) -> PyResult<Option<SyncResult<'py>>> {
        let timeout = timeout
            .map(|t| settings::duration("timeout", t))
            .transpose()?;
        match self.with_pool(py, move |p, out| p.wait_shared(timeout, out))? {
            Some(slot) => self.sync_result(py, slot, final_out).map(Some),
            None => Ok(None),
        }
    }

    /// A partial reset (gymnasium's `reset_mask`): envs with `mask[i]` start their next
    /// scheduled episode, the others keep their state and their current observation is
    /// written again. `mask`: bool array, one per env. Returns the result as `step` does
    /// (every env's row). Needs a full reset first.
    fn reset_envs<'py>(
        &self,
        py: Python<'py>,
        mask: &Bound<'_, PyAny>,
    ) -> PyResult<SyncResult<'py>> {
        let arr: PyReadonlyArray1<'_, bool> = mask.extract().map_err(|_| {
            PyValueError::new_err(format!(
                "reset_mask must be a 1-D bool numpy array of shape ({},)",
                self.num_envs
            ))
        })?;
        let m: Vec<bool> = arr.as_array().to_vec();
        if m.len() != self.num_envs {
            return Err(PyValueError::new_err(format!(
                "reset_mask must have shape ({},), got ({},)",
                self.num_envs,
                m.len()
            )));
        }
        let slot = self.with_pool(py, move |p, out| p.reset_envs(&m, out))?;
        self.sync_result(py, slot, None)
    }

    /// Zero-copy uint8 views of the shared batch slots (`num_envs x obs_bytes` bytes each), in
    /// slot order. Their base owns the mapping, so they stay valid after `close()`.
    fn shared_views<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let guard = lock_gil_free(py, &self.pool)?;
        let pool = guard
            .as_ref()
            .ok_or_else(|| PyRuntimeError::new_err("the pool is closed"))?;
        let buffer = pool
            .shared_buffer()
            .ok_or_else(|| PyRuntimeError::new_err("the pool has no shared batch buffer"))?;
        let len = self.num_envs * self.obs_bytes;
        let list = PyList::empty(py);
        let mut slot = 0;
        loop {
            let ptr = pool.shared_obs_ptr(slot);
            if ptr.is_null() {
                break;
            }
            let holder = Bound::new(
                py,
                SharedBatchHolder {
                    _buffer: buffer.clone(),
                },
            )?;
            // SAFETY: the slot lies inside the mapping owned (via the Arc) by `holder`, the
            // array's base; workers write it only during a whole-batch call.
            let view = unsafe { ArrayView1::from_shape_ptr(len, ptr) };
            let arr = unsafe { PyArray1::<u8>::borrow_from_array(&view, holder.into_any()) };
            list.append(arr)?;
            slot += 1;
        }
        Ok(list)
    }

    /// Make the next whole-batch call write batch slot `slot` (an index into
    /// `shared_views()`); the turns go on from there. `ValueError` for a slot that does not
    /// exist.
    fn select_slot(&self, py: Python<'_>, slot: usize) -> PyResult<()> {
        self.with_pool(py, move |p, _| p.select_slot(slot))
    }

    /// Replace the episode-seed schedule (JSON `{"base": .., "set": .., "policy": ..}`) and
    /// restart every env's episode count; call a reset next.
    fn set_seeds(&self, py: Python<'_>, seeds_json: &str) -> PyResult<()> {
        let seeds: SeedSchedule = serde_json::from_str(seeds_json)
            .map_err(|e| PyValueError::new_err(format!("invalid seed schedule: {e}")))?;
        self.with_pool(py, move |p, _| p.set_seeds(seeds))
    }
}
