//! Conversion of Python observation specs (`rogue_gym.envs.ObsSpec`) into the engine's.

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use rogue_gym_engine::{Dtype, Encoding, ObsSpec, StatusFlags};

/// Parse `(encoding, dtype, status, normalize_status, history)` from an `ObsSpec` named tuple,
/// a plain tuple or a dict with those keys.
pub fn parse_spec(obj: &Bound<'_, PyAny>) -> PyResult<ObsSpec> {
    let field = |name: &str, idx: usize| -> PyResult<Bound<'_, PyAny>> {
        if let Ok(d) = obj.cast::<PyDict>() {
            return d
                .get_item(name)?
                .ok_or_else(|| PyValueError::new_err(format!("observation spec lacks {name:?}")));
        }
        if let Ok(t) = obj.cast::<PyTuple>() {
            return t.get_item(idx);
        }
        obj.getattr(name)
    };
    let encoding: String = field("encoding", 0)?.extract()?;
    let dtype: String = field("dtype", 1)?.extract()?;
    let status: u16 = field("status", 2)?
        .extract()
        .map_err(|_| PyTypeError::new_err("observation spec status must be an int bit mask"))?;
    let normalize_status: bool = field("normalize_status", 3)?.extract()?;
    let history: bool = field("history", 4)?.extract()?;
    let encoding: Encoding = match encoding.as_str() {
        "status_vector" => Ok(Encoding::StatusVector),
        other => other.parse(),
    }
    .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let dtype: Dtype = dtype
        .parse()
        .map_err(|e: rogue_gym_engine::ObsError| PyValueError::new_err(e.to_string()))?;
    if status > StatusFlags::FULL.0 {
        return Err(PyValueError::new_err(format!(
            "status flags {status:#x} out of range (at most {:#x})",
            StatusFlags::FULL.0
        )));
    }
    Ok(ObsSpec {
        encoding,
        dtype,
        status: StatusFlags(status),
        normalize_status,
        history,
    })
}
