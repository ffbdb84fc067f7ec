//! The whole-batch API (gymnasium's `step`/`reset` and their split halves): every env at once,
//! every per-env output written by the workers in place into the next shared batch slot,
//! results as [`SyncResult`]s.

use numpy::ndarray::ArrayView1;
use numpy::{PyArray1, PyReadonlyArray1};
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
    /// uint8 bytes for hosted envs whose actions travel so). The workers write every per-env
    /// output in place into the next batch slot (see `slot_views`). Returns `(slot, summary,
    /// extras)`.
    fn step<'py>(&self, py: Python<'py>, actions: &Bound<'_, PyAny>) -> PyResult<SyncResult<'py>> {
        let acts = self.owned_actions(actions, self.num_envs)?;
        let answer = self.with_pool(py, move |p, _| p.step_slot(acts.as_actions()))?;
        self.sync_result(py, answer)
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
    #[pyo3(signature = (timeout = None))]
    fn wait<'py>(
        &self,
        py: Python<'py>,
        timeout: Option<f64>,
    ) -> PyResult<Option<SyncResult<'py>>> {
        let timeout = timeout
            .map(|t| settings::duration("timeout", t))
            .transpose()?;
        match self.with_pool(py, move |p, _| p.wait_shared(timeout))? {
            Some(answer) => self.sync_result(py, answer).map(Some),
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
        let answer = self.with_pool(py, move |p, _| p.reset_envs_slot(&m))?;
        self.sync_result(py, answer)
    }

    /// Zero-copy uint8 views of every batch slot's areas, in slot order: `(obs, columns,
    /// final, extra)` each (`num_envs x obs_bytes` observations; the columns area, see
    /// `column_layout`; the SAME_STEP final observations or `None`; the extra-info room,
    /// `num_envs x extra_bytes`, or `None`). Their base owns the mapping, so they stay valid
    /// after `close()`. The workers write a slot's rows during the whole-batch call that
    /// names it, and only then.
    fn slot_views<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let guard = lock_gil_free(py, &self.pool)?;
        let pool = guard
            .as_ref()
            .ok_or_else(|| PyRuntimeError::new_err("the pool is closed"))?;
        let buffer = pool
            .shared_buffer()
            .ok_or_else(|| PyRuntimeError::new_err("the pool has no shared batch buffer"))?;
        let layout = pool.slot_layout();
        let n = layout.num_envs;
        let view = |ptr: *const u8, len: usize| -> PyResult<Bound<'py, PyAny>> {
            let holder = Bound::new(
                py,
                SharedBatchHolder {
                    _buffer: buffer.clone(),
                },
            )?;
            // SAFETY: the area lies inside the mapping owned (via the Arc) by `holder`, the
            // array's base.
            let v = unsafe { ArrayView1::from_shape_ptr(len, ptr) };
            Ok(unsafe { PyArray1::<u8>::borrow_from_array(&v, holder.into_any()) }.into_any())
        };
        let list = PyList::empty(py);
        for slot in 0..pool.batch_slots() {
            let base = pool.shared_obs_ptr(slot);
            // SAFETY: every offset below stays inside the slot (see `SlotLayout`).
            let at = |off: usize| unsafe { base.add(off) };
            let obs = view(base, n * layout.obs_bytes)?;
            let cols = view(at(layout.columns_offset()), layout.columns_bytes())?;
            let fin = if layout.final_obs {
                Some(view(at(layout.final_offset()), n * layout.obs_bytes)?)
            } else {
                None
            };
            let extra = if layout.extra_bytes > 0 {
                Some(view(at(layout.extra_offset()), n * layout.extra_bytes)?)
            } else {
                None
            };
            list.append((obs, cols, fin, extra))?;
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
