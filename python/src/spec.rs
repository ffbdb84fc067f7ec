//! Observation specs from Python (`rogue_gym.envs.ObsSpec`, a tuple or a dict) into the
//! engine's. The engine's [`ObsSpec::from_json`] is the one parser: this module only gathers the
//! five fields into its JSON form.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use rogue_gym_engine::ObsSpec;
use serde_json::{Map, Value};

/// The fields of an observation spec, in tuple order.
const FIELDS: [&str; 5] = ["encoding", "dtype", "status", "normalize_status", "history"];

/// Parse an `ObsSpec` named tuple, a plain tuple or a dict with the five fields.
pub fn parse_spec(obj: &Bound<'_, PyAny>) -> PyResult<ObsSpec> {
    let mut map = Map::new();
    for (idx, name) in FIELDS.iter().enumerate() {
        let item = if let Ok(d) = obj.cast::<PyDict>() {
            d.get_item(name)?
        } else if let Ok(t) = obj.cast::<PyTuple>() {
            Some(t.get_item(idx)?)
        } else {
            Some(obj.getattr(name)?)
        };
        let Some(item) = item else { continue };
        let value = if let Ok(b) = item.extract::<bool>() {
            Value::Bool(b)
        } else if let Ok(n) = item.extract::<u64>() {
            Value::from(n)
        } else if let Ok(n) = item.extract::<i64>() {
            Value::from(n)
        } else if let Ok(s) = item.extract::<String>() {
            Value::String(s)
        } else {
            return Err(PyValueError::new_err(format!(
                "observation spec field {name} must be a str, an int or a bool, got {}",
                item.get_type().name()?
            )));
        };
        map.insert(name.to_string(), value);
    }
    ObsSpec::from_json(&Value::Object(map)).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// `obs_spec(spec) -> dict`: the spec checked and normalised by the engine's parser (canonical
/// names: `symbol_onehot`..., `uint8`/`float32`).
#[pyfunction]
pub fn normalize_obs_spec<'py>(
    py: Python<'py>,
    spec: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let s = parse_spec(spec)?;
    let d = PyDict::new(py);
    if let Value::Object(m) = s.to_json() {
        for (k, v) in m {
            match v {
                Value::String(x) => d.set_item(k, x)?,
                Value::Bool(x) => d.set_item(k, x)?,
                Value::Number(x) => d.set_item(k, x.as_u64().unwrap_or(0))?,
                _ => {}
            }
        }
    }
    Ok(d)
}
