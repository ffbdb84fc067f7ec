//! The `"python"` env kind: a gymnasium env written in Python, hosted in a pool worker.
//!
//! The worker runs the pool's Rust loop with the GIL released; each call on a [`HostedEnv`]
//! takes the GIL and calls its adapter (`rogue_gym.hosted.adapter.HostedEnv`), which builds the
//! env from the caller's cloudpickled callable and turns observations, actions and infos into
//! the flat bytes the pool carries. The env's JSON spec is
//! `{"kind": "python", "spec": <EnvSpec>, "adapter": {...}}`: the [`EnvSpec`] the front end
//! computed (the supervisor gets the same one), and what the adapter needs.
//!
//! A Python exception becomes an [`EnvError`] whose message is the adapter's encoding of it
//! (type, message, worker-side traceback), which the front end decodes to re-raise it.

use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyTuple};
use rogue_gym_pool::{Env, EnvError, EnvSpec, StepOutcome};
use serde_json::Value;

/// The kind name of hosted envs.
pub(crate) const KIND: &str = "python";
/// The Python module of the adapter.
const ADAPTER_MODULE: &str = "rogue_gym.hosted.adapter";

/// One hosted env: its adapter object and the spec the pool agreed on.
struct HostedEnv {
    adapter: Py<PyAny>,
    /// The adapter's exception class for encoded env exceptions.
    encoded: Py<PyAny>,
    spec: EnvSpec,
    /// The last call left info to hand over ([`Env::extra_info`]).
    has_info: bool,
}

/// The message of a Python error: the adapter's encoding, or `Type: message` for anything else.
fn env_error(py: Python<'_>, encoded: &Py<PyAny>, e: PyErr) -> EnvError {
    let is_encoded = e
        .get_type(py)
        .is_subclass(encoded.bind(py))
        .unwrap_or(false);
    if is_encoded && let Ok(s) = e.value(py).str() {
        return EnvError::new(s.to_string());
    }
    EnvError::new(e.to_string())
}

/// Build env number `index` of a pool (the [`rogue_gym_pool::EnvCtor`] of [`KIND`]).
pub(crate) fn make_hosted_env(v: &Value, index: u64) -> Result<Box<dyn Env>, EnvError> {
    let spec: EnvSpec = v
        .get("spec")
        .cloned()
        .ok_or_else(|| EnvError::new("python env: the spec has no \"spec\" field"))
        .and_then(|s| {
            serde_json::from_value(s).map_err(|e| EnvError::new(format!("python env spec: {e}")))
        })?;
    let adapter_cfg = v
        .get("adapter")
        .ok_or_else(|| EnvError::new("python env: the spec has no \"adapter\" field"))?
        .to_string();
    Python::attach(|py| {
        let module = py
            .import(ADAPTER_MODULE)
            .map_err(|e| EnvError::new(format!("cannot import {ADAPTER_MODULE}: {e}")))?;
        let encoded = module
            .getattr("EncodedEnvError")
            .map_err(|e| EnvError::new(e.to_string()))?
            .unbind();
        let adapter = module
            .getattr("HostedEnv")
            .and_then(|cls| cls.call_method1("build", (adapter_cfg, index)))
            .map_err(|e| env_error(py, &encoded, e))?
            .unbind();
        Ok(Box::new(HostedEnv {
            adapter,
            encoded,
            spec,
            has_info: false,
        }) as Box<dyn Env>)
    })
}

/// The bytes an adapter method returned (`what` names it in the error).
fn returned_bytes<'a>(b: &'a Bound<'_, PyAny>, what: &str) -> Result<&'a [u8], EnvError> {
    b.cast::<PyBytes>()
        .map(|b| b.as_bytes())
        .map_err(|_| EnvError::new(format!("the adapter's {what} returned non-bytes")))
}

/// Copy an observation the adapter returned (bytes, at most the observation's room; the rest
/// is padding and zeroed).
fn write_obs(b: &Bound<'_, PyAny>, obs: &mut [u8]) -> Result<(), EnvError> {
    let bytes = returned_bytes(b, "observation")?;
    if bytes.len() > obs.len() {
        return Err(EnvError::new(format!(
            "the observation takes {} bytes; its space has room for {}",
            bytes.len(),
            obs.len()
        )));
    }
    obs[..bytes.len()].copy_from_slice(bytes);
    obs[bytes.len()..].fill(0);
    Ok(())
}

impl HostedEnv {
    /// Call `adapter.step(arg)` and unpack `(obs, reward, terminated, truncated, has_info)`.
    fn step_with<'py>(
        &mut self,
        py: Python<'py>,
        arg: Bound<'py, PyAny>,
        obs: &mut [u8],
    ) -> Result<StepOutcome, EnvError> {
        let err = |e: PyErr| env_error(py, &self.encoded, e);
        let r = self
            .adapter
            .bind(py)
            .call_method1(intern!(py, "step"), (arg,))
            .map_err(err)?;
        let t = r
            .cast::<PyTuple>()
            .map_err(|_| EnvError::new("the adapter's step returned a non-tuple"))?;
        write_obs(&t.get_item(0).map_err(err)?, obs)?;
        let reward: f64 = t.get_item(1).and_then(|x| x.extract()).map_err(err)?;
        let terminated: bool = t.get_item(2).and_then(|x| x.extract()).map_err(err)?;
        let truncated: bool = t.get_item(3).and_then(|x| x.extract()).map_err(err)?;
        self.has_info = t.get_item(4).and_then(|x| x.extract()).map_err(err)?;
        Ok(StepOutcome {
            reward,
            terminated,
            truncated,
        })
    }
}

impl Env for HostedEnv {
    fn spec(&self) -> EnvSpec {
        self.spec.clone()
    }

    fn reset(&mut self, seed: u64, obs: &mut [u8]) -> Result<(), EnvError> {
        self.reset_episode(seed, 0, obs)
    }

    fn reset_episode(&mut self, seed: u64, episode: u64, obs: &mut [u8]) -> Result<(), EnvError> {
        Python::attach(|py| {
            let err = |e: PyErr| env_error(py, &self.encoded, e);
            let r = self
                .adapter
                .bind(py)
                .call_method1(intern!(py, "reset"), (seed, episode))
                .map_err(err)?;
            let t = r
                .cast::<PyTuple>()
                .map_err(|_| EnvError::new("the adapter's reset returned a non-tuple"))?;
            write_obs(&t.get_item(0).map_err(err)?, obs)?;
            self.has_info = t.get_item(1).and_then(|x| x.extract()).map_err(err)?;
            Ok(())
        })
    }

    fn step(&mut self, action: usize, obs: &mut [u8]) -> Result<StepOutcome, EnvError> {
        Python::attach(|py| {
            let arg = action
                .into_pyobject(py)
                .map_err(|e| EnvError::new(e.to_string()))?;
            self.step_with(py, arg.into_any(), obs)
        })
    }

    fn step_bytes(&mut self, action: &[u8], obs: &mut [u8]) -> Result<StepOutcome, EnvError> {
        Python::attach(|py| {
            let arg = PyBytes::new(py, action).into_any();
            self.step_with(py, arg, obs)
        })
    }

    fn extra_info(&mut self, out: &mut [u8]) -> Result<usize, EnvError> {
        if !std::mem::take(&mut self.has_info) {
            return Ok(0);
        }
        Python::attach(|py| {
            let b = self
                .adapter
                .bind(py)
                .call_method0(intern!(py, "take_info"))
                .map_err(|e| env_error(py, &self.encoded, e))?;
            let bytes = returned_bytes(&b, "take_info")?;
            if bytes.len() > out.len() {
                return Err(EnvError::new(format!(
                    "the env's info takes {} bytes pickled, more than the {} reserved per env and step; pass a larger info_bytes to the vector env",
                    bytes.len(),
                    out.len()
                )));
            }
            out[..bytes.len()].copy_from_slice(bytes);
            Ok(bytes.len())
        })
    }

    fn call(&mut self, request: &[u8]) -> Result<Vec<u8>, EnvError> {
        Python::attach(|py| {
            let b = self
                .adapter
                .bind(py)
                .call_method1(intern!(py, "call"), (PyBytes::new(py, request),))
                .map_err(|e| env_error(py, &self.encoded, e))?;
            Ok(returned_bytes(&b, "call")?.to_vec())
        })
    }

    fn observe(&self, obs: &mut [u8]) -> Result<(), EnvError> {
        Python::attach(|py| {
            let b = self
                .adapter
                .bind(py)
                .call_method0("observe")
                .map_err(|e| env_error(py, &self.encoded, e))?;
            write_obs(&b, obs)
        })
    }
}

impl Drop for HostedEnv {
    /// Close the Python env when the worker lets go of it (at exit).
    fn drop(&mut self) {
        Python::attach(|py| {
            let _ = self.adapter.bind(py).call_method0("close");
        });
    }
}
