//! Actions as the caller passed them, checked and owned so that the pool can use them
//! without the GIL.

use numpy::PyReadonlyArray1;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use rogue_gym_pool::Actions;

use super::PyPool;

/// Actions owned for a call made without the GIL.
pub(super) enum OwnedActions {
    /// One index per env (int64).
    Indices(Vec<i64>),
    /// `action_bytes` raw bytes per env (hosted envs).
    Bytes(Vec<u8>),
}

impl OwnedActions {
    /// The actions as the pool takes them.
    pub(super) fn as_actions(&self) -> Actions<'_> {
        match self {
            OwnedActions::Indices(a) => Actions::Indices(a),
            OwnedActions::Bytes(b) => Actions::Bytes(b),
        }
    }
}

impl PyPool {
    /// Take the caller's actions (their values are checked by the pool, once: see
    /// [`Actions::check`]): a 1-D int64 array (one index per env), or for hosted envs whose
    /// actions are `action_bytes` raw bytes, a 1-D uint8 array of them, env after env.
    pub(super) fn owned_actions(&self, actions: &Bound<'_, PyAny>) -> PyResult<OwnedActions> {
        if self.action_bytes == 0 {
            let arr: PyReadonlyArray1<'_, i64> = actions.extract().map_err(|_| {
                PyTypeError::new_err("actions must be a 1-D int64 numpy array (one action per env)")
            })?;
            return Ok(OwnedActions::Indices(arr.as_array().to_vec()));
        }
        let arr: PyReadonlyArray1<'_, u8> = actions.extract().map_err(|_| {
            PyTypeError::new_err("this env's actions travel as raw bytes: pass a 1-D uint8 array")
        })?;
        Ok(OwnedActions::Bytes(arr.as_array().to_vec()))
    }
}
