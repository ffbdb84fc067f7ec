//! Native module of the `rogue_gym` Python package (work in progress).
use pyo3::prelude::*;

/// The `rogue_gym._native` module.
#[pymodule]
fn _native(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
