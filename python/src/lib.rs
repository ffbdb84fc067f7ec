//! Native module of the `rogue_gym` Python package: the engine (`Game`), the environment
//! pool (`Pool`, with zero-copy views of worker blocks) and the worker entry point
//! (`worker_main`, run by `python -m rogue_gym.worker`).
//!
//! Every Rust error is mapped to a Python exception; nothing panics across the FFI boundary.

#![deny(missing_docs)]

use pyo3::prelude::*;

mod game;
mod pool;
mod spec;
mod summary;

/// Run a pool worker with the given arguments (everything after `python -m rogue_gym.worker`)
/// and return its exit code. The GIL is released for the worker's whole life.
#[pyfunction]
fn worker_main(py: Python<'_>, argv: Vec<String>) -> i32 {
    py.detach(|| {
        let registry = rogue_gym_pool::EnvRegistry::with_defaults();
        rogue_gym_pool::worker_main(&argv, &registry)
    })
}

/// The `rogue_gym._native` module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<game::PyGame>()?;
    m.add_class::<pool::PyPool>()?;
    m.add_class::<pool::BlockHolder>()?;
    m.add_class::<pool::SharedBatchHolder>()?;
    m.add("RECORD_BYTES", pool::RECORD_BYTES)?;
    m.add_function(wrap_pyfunction!(game::action_from_key, m)?)?;
    m.add_function(wrap_pyfunction!(worker_main, m)?)?;
    m.add_function(wrap_pyfunction!(summary::floor_summary, m)?)?;
    m.add("ACTION_KEYS", ".hjklnbuy>s")?;
    m.add("NUM_ACTIONS", rogue_gym_engine::NUM_ACTIONS)?;
    Ok(())
}
