//! The whole-batch API (gymnasium's `step`/`reset` and their split halves): every env at once,
//! every per-env output written by the workers in place into the next shared batch slot,
//! results as [`SyncResult`]s. The names are the pool's: `step` is `send_step` then `wait`.

use numpy::ndarray::ArrayView1;
use numpy::{PyArray1, PyArrayDescrMethods, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyList;
use rogue_gym_pool::{Received, SeedSchedule};

use super::PyPool;
use super::results::{Joined, joined, summary};
use crate::gil::lock_gil_free;
use crate::holders::SharedBatchHolder;
use crate::settings;

/// A whole-batch call's result: `(slot, summary, extras)`.
type SyncResult<'py> = (usize, usize, Option<Joined<'py>>);

#[pymethods]
impl PyPool {
    /// A sync step of every env: `actions` (int64, one per env, range-checked by the pool;
    /// or raw uint8 bytes for hosted envs whose actions travel so). The workers write every
    /// per-env output in place into the next batch slot (see `slot_views`). Returns `(slot,
    /// summary, extras)`.
    fn step<'py>(&self, py: Python<'py>, actions: &Bound<'_, PyAny>) -> PyResult<SyncResult<'py>> {
        let acts = self.owned_actions(actions)?;
        let answer = self.with_pool(py, move |p| p.step(acts.as_actions()))?;
        self.sync_result(py, answer)
    }

    /// The first half of a sync step (gymnasium's `step_async`): send `actions`; the workers
    /// step meanwhile. Returns the slot they write. Collect with `wait`.
    fn send_step(&self, py: Python<'_>, actions: &Bound<'_, PyAny>) -> PyResult<usize> {
        let acts = self.owned_actions(actions)?;
        self.with_pool(py, move |p| p.send_step(acts.as_actions()))
    }

    /// The first half of a reset (gymnasium's `reset_async`); returns the slot. Collect with
    /// `wait`. Without `mask`, every env resets. With `mask` (gymnasium's `reset_mask`: a 1-D
    /// bool or uint8 array, one entry per env, read as bytes, any nonzero byte true), a partial
    /// reset: masked envs start their next scheduled episode, the others keep their state and
    /// their current observation is written again; it needs a full reset first.
    #[pyo3(signature = (mask = None))]
    fn send_reset(&self, py: Python<'_>, mask: Option<&Bound<'_, PyAny>>) -> PyResult<usize> {
        let mask = mask.map(|m| self.reset_mask(py, m)).transpose()?;
        self.with_pool(py, move |p| p.send_reset(mask.as_deref()))
    }

    /// The second half of `send_step`/`send_reset`: wait at most `timeout` seconds (`None`:
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
        match self.with_pool(py, move |p| p.wait(timeout))? {
            Some(answer) => self.sync_result(py, answer).map(Some),
            None => Ok(None),
        }
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
            // SAFETY: slot `slot` lies inside the buffer.
            let base = unsafe { buffer.as_ptr().add(slot * layout.bytes()) }.cast_const();
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
        self.with_pool(py, move |p| p.select_slot(slot))
    }

    /// Replace the episode-seed schedule (JSON `{"base": .., "set": .., "policy": ..}`) and
    /// restart every env's episode count; call a reset next.
    fn set_seeds(&self, py: Python<'_>, seeds_json: &str) -> PyResult<()> {
        let seeds: SeedSchedule = serde_json::from_str(seeds_json)
            .map_err(|e| PyValueError::new_err(format!("invalid seed schedule: {e}")))?;
        self.with_pool(py, move |p| p.set_seeds(seeds))
    }
}

impl PyPool {
    /// A reset mask from Python: a 1-D bool (or uint8) array, read as bytes (a numpy bool
    /// array may hold any byte, so never as Rust `bool`).
    fn reset_mask(&self, py: Python<'_>, mask: &Bound<'_, PyAny>) -> PyResult<Vec<bool>> {
        let shape_err = || {
            PyValueError::new_err(format!(
                "reset_mask must be a 1-D bool numpy array of shape ({},)",
                self.num_envs
            ))
        };
        let arr = mask.cast::<PyUntypedArray>().map_err(|_| shape_err())?;
        let dtype = arr.dtype();
        if arr.ndim() != 1 || dtype.itemsize() != 1 || !matches!(dtype.kind(), b'b' | b'u') {
            return Err(shape_err());
        }
        // Its length is the pool's to check (`Pool::send_reset`: a `ValueError` too).
        let bytes = arr.call_method1("view", (numpy::dtype::<u8>(py),))?;
        let bytes = bytes.cast::<PyArray1<u8>>()?.readonly();
        Ok(bytes.as_array().iter().map(|&b| b != 0).collect())
    }

    /// The result of a whole-batch call: the slot the workers wrote every row of in place,
    /// the `SUMMARY_*` bits, and the extra info (see `Joined`).
    fn sync_result<'py>(&self, py: Python<'py>, got: Received) -> PyResult<SyncResult<'py>> {
        let slot = got
            .slot()
            .ok_or_else(|| PyRuntimeError::new_err("a whole-batch call's rows are a view"))?;
        Ok((
            slot,
            summary(&got, true),
            joined(py, &got.extras, self.num_envs)?,
        ))
    }
}
