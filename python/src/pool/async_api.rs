//! The EnvPool-style async API, env by env: `async_reset`, `send` to any envs, and `recv` of
//! the first envs ready, whose records are written straight into the `recv` column buffer.

use numpy::PyArray1;
use numpy::PyReadonlyArray1;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use rogue_gym_pool::{Received, RecvWant};

use super::PyPool;
use super::results::{joined, summary};
use crate::settings;

#[pymethods]
impl PyPool {
    /// Async: have `recv` hand rows that are one run of envs in one slot out as views (see
    /// `recv`).
    fn async_views(&self, py: Python<'_>, on: bool) -> PyResult<()> {
        self.with_pool(py, move |p| {
            p.set_async_views(on);
            Ok(())
        })
    }

    /// Async: reset every env; collect the results with `recv()`. `lent`: the batch slots the
    /// caller has lent out (bit `s`: slot `s`), where no async answer is written until the next
    /// call that says (`Pool::lend_slots`).
    #[pyo3(signature = (lent=0))]
    fn async_reset(&self, py: Python<'_>, lent: u64) -> PyResult<()> {
        self.with_pool(py, move |p| {
            p.lend_slots(lent)?;
            p.async_reset()
        })
    }

    /// Async: send `actions` (int64 indices, or raw uint8 bytes for hosted envs whose actions
    /// travel so) to `env_ids` (a 1-D int64 array, or a sequence of ints: any envs, each at
    /// most once until received); `lent` as `async_reset`'s.
    #[pyo3(signature = (actions, env_ids, lent=0))]
    fn send(
        &self,
        py: Python<'_>,
        actions: &Bound<'_, PyAny>,
        env_ids: &Bound<'_, PyAny>,
        lent: u64,
    ) -> PyResult<()> {
        let env_ids: Vec<usize> = match env_ids.extract::<PyReadonlyArray1<'_, i64>>() {
            Ok(a) => a
                .as_array()
                .iter()
                .map(|&i| {
                    usize::try_from(i).map_err(|_| {
                        PyValueError::new_err(format!(
                            "env_id {i} is negative: env ids are 0 to {}",
                            self.num_envs - 1
                        ))
                    })
                })
                .collect::<PyResult<_>>()?,
            Err(_) => env_ids.extract().map_err(|_| {
                PyTypeError::new_err("env_id must be a 1-D int64 array or a sequence of ints")
            })?,
        };
        let acts = self.owned_actions(actions)?;
        self.with_pool(py, move |p| {
            p.lend_slots(lent)?;
            p.send(acts.as_actions(), &env_ids)
        })
    }

    /// Async: the first envs ready, `(rows, summary, extras, env_ids, obs, view)`: their
    /// per-env values decoded into the `recv` column buffer (its first `rows` entries), the
    /// `SUMMARY_*` bits, the joined extras of the rows that wrote some (see `Joined`), the
    /// int64 env id of each row, and their observations as one uint8 array (`rows x
    /// obs_bytes`, a fresh copy); or, where the rows are one run of envs in one slot
    /// (`async_views`), `obs` is `None` and `view` is `(slot, first)`: the rows are envs
    /// `first..first + rows` of batch slot `slot` (its observations and columns, see
    /// `slot_views`), unchanged until those envs' next answer but one. `min_batch`, `max_batch` (default both `batch_size`) and
    /// `timeout` (seconds) as `RecvWant`: return once `max_batch` are ready, or at the
    /// deadline with at least `min_batch` (else `TimeoutError`, nothing lost).
    #[pyo3(signature = (min_batch=None, max_batch=None, timeout=None))]
    fn recv<'py>(
        &self,
        py: Python<'py>,
        min_batch: Option<usize>,
        max_batch: Option<usize>,
        timeout: Option<f64>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let timeout = timeout
            .map(|t| settings::duration("timeout", t))
            .transpose()?;
        let want = RecvWant::resolve(min_batch, max_batch, timeout, self.batch_size);
        let got: Received = self.with_pool(py, move |p| p.recv_want(want))?;
        let rows = got.env_ids.len();
        // A view's rows are in its slot, columns included: nothing to write.
        if got.view.is_none() {
            self.write_recv_columns(&got)?;
        }
        let summary = summary(&got, false);
        let extras = joined(py, &got.extras, rows)?;
        let ids: Vec<i64> = got.env_ids.iter().map(|&e| e as i64).collect();
        let obs = match got.view {
            Some(_) => py.None().into_bound(py),
            None => PyArray1::from_vec(py, got.obs).into_any(),
        };
        PyTuple::new(
            py,
            [
                rows.into_pyobject(py)?.into_any(),
                summary.into_pyobject(py)?.into_any(),
                extras.into_pyobject(py)?.into_any(),
                PyArray1::from_vec(py, ids).into_any(),
                obs,
                got.view.into_pyobject(py)?.into_any(),
            ],
        )
    }
}
