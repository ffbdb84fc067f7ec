//! The owners of shared memory behind zero-copy numpy views: a worker block of the async API,
//! and the pool's batch buffer of the sync calls.

use std::sync::Mutex;

use pyo3::prelude::*;
use rogue_gym_pool::Block;

/// Owner of one worker block (an iceoryx2 sample) behind zero-copy numpy views.
///
/// The views returned by `Pool.recv()` have this object as their base: the shared-memory
/// sample stays mapped and unchanged for as long as any view (or this object) lives, even after
/// the pool is closed. There is no way to release it early (a dangling view is impossible).
#[pyclass(module = "rogue_gym._native", name = "BlockHolder", frozen)]
pub struct BlockHolder {
    pub(crate) block: Mutex<Block>,
}

#[pymethods]
impl BlockHolder {
    /// The worker that produced the block.
    #[getter]
    fn worker(&self) -> usize {
        self.block.lock().map(|b| b.worker()).unwrap_or(usize::MAX)
    }
}

/// Owner of the pool's shared batch buffer (the observation slots written by the workers)
/// behind the zero-copy views returned by `Pool.shared_views()`. The mapping stays valid for
/// as long as a view (or this object) lives, even after the pool is closed.
#[pyclass(module = "rogue_gym._native", name = "SharedBatchHolder", frozen)]
pub struct SharedBatchHolder {
    pub(crate) _buffer: std::sync::Arc<rogue_gym_ipc::SharedBuffer>,
}
