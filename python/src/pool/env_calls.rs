//! Env operations off the hot path (`call`, `get_attr`, `render`, ... as pickled requests)
//! and the parts of no fixed size of the next step's actions.

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyList};

use super::PyPool;

#[pymethods]
impl PyPool {
    /// Call into envs off the hot path: `requests` are `(env id, request bytes)`; returns
    /// `(env id, reply bytes)` in the same order (GIL released while the workers answer).
    fn call_envs<'py>(
        &self,
        py: Python<'py>,
        requests: Vec<(usize, Vec<u8>)>,
    ) -> PyResult<Bound<'py, PyList>> {
        let replies = self.with_pool(py, move |p| p.call_envs(&requests))?;
        let list = PyList::empty(py);
        for (env, bytes) in replies {
            list.append((env, PyBytes::new(py, &bytes)))?;
        }
        Ok(list)
    }

    /// Stage the parts of no fixed size of the next step's actions, `(env id, bytes)` each: the
    /// next step command to each env's worker carries them, and the env takes them just before
    /// it steps (hosted envs: `set_action_extra`).
    fn stage_action_extras(&self, py: Python<'_>, extras: Vec<(usize, Vec<u8>)>) -> PyResult<()> {
        self.with_pool(py, move |p| p.stage_action_extras(&extras))
    }
}
