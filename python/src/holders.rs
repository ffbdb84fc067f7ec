//! The owner of shared memory behind zero-copy numpy views: the pool's batch buffer of the
//! sync calls.

use pyo3::prelude::*;

/// Owner of the pool's shared batch buffer (the observation slots written by the workers)
/// behind the zero-copy views returned by `Pool.shared_views()`. The mapping stays valid for
/// as long as a view (or this object) lives, even after the pool is closed.
#[pyclass(module = "rogue_gym._native", name = "SharedBatchHolder", frozen)]
pub struct SharedBatchHolder {
    pub(crate) _buffer: std::sync::Arc<rogue_gym_ipc::SharedBuffer>,
}
