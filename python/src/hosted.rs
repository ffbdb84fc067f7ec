//! The `"python"` env kind: a gymnasium env written in Python, hosted in a pool worker.
//!
//! The worker runs the pool's Rust loop with the GIL released; each call on a [`HostedEnv`]
//! takes the GIL and calls its adapter (`rogue_gym.hosted.adapter.HostedEnv`), which builds the
//! env from the caller's cloudpickled callable, decodes actions, writes each observation
//! straight into the destination the worker lends it (by address, during the call only) and
//! returns infos as bytes (typed rows or pickles). The env's JSON spec is
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
    /// The info bytes of the current command, to hand over ([`Env::extra_info`]).
    info: Vec<u8>,
    /// The last call was a successful step: a reset now is its autoreset (same command).
    after_step: bool,
}

/// The message of a Python error: the adapter's encoding, or `Type: message` for anything else.
pub(crate) fn env_error(py: Python<'_>, encoded: &Py<PyAny>, e: PyErr) -> EnvError {
    let is_encoded = e
        .get_type(py)
        .is_subclass(encoded.bind(py))
        .unwrap_or(false);
    if is_encoded && let Ok(s) = e.value(py).str() {
        return EnvError::new(s.to_string());
    }
    EnvError::new(e.to_string())
}

/// The spec and adapter config (JSON text) of a hosted kind's JSON spec.
pub(crate) fn spec_and_adapter(v: &Value) -> Result<(EnvSpec, String), EnvError> {
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
    Ok((spec, adapter_cfg))
}

/// Build an adapter: `module.class.build(*args)`; returns it with the module's exception class
/// for encoded env errors.
pub(crate) fn build_adapter<'py>(
    py: Python<'py>,
    module: &str,
    class: &str,
    args: impl pyo3::call::PyCallArgs<'py>,
) -> Result<(Py<PyAny>, Py<PyAny>), EnvError> {
    let m = py
        .import(module)
        .map_err(|e| EnvError::new(format!("cannot import {module}: {e}")))?;
    let encoded = py
        .import(ADAPTER_MODULE)
        .and_then(|a| a.getattr("EncodedEnvError"))
        .map_err(|e| EnvError::new(e.to_string()))?
        .unbind();
    let adapter = m
        .getattr(class)
        .and_then(|cls| cls.call_method1("build", args))
        .map_err(|e| env_error(py, &encoded, e))?
        .unbind();
    Ok((adapter, encoded))
}

/// Build env number `index` of a pool (the [`rogue_gym_pool::EnvCtor`] of [`KIND`]).
pub(crate) fn make_hosted_env(v: &Value, index: u64) -> Result<Box<dyn Env>, EnvError> {
    let (spec, adapter_cfg) = spec_and_adapter(v)?;
    Python::attach(|py| {
        let (adapter, encoded) =
            build_adapter(py, ADAPTER_MODULE, "HostedEnv", (adapter_cfg, index))?;
        Ok(Box::new(HostedEnv {
            adapter,
            encoded,
            spec,
            info: Vec::new(),
            after_step: false,
        }) as Box<dyn Env>)
    })
}

/// The bytes an adapter method returned (`what` names it in the error).
pub(crate) fn returned_bytes<'a>(
    b: &'a Bound<'_, PyAny>,
    what: &str,
) -> Result<&'a [u8], EnvError> {
    b.cast::<PyBytes>()
        .map(|b| b.as_bytes())
        .map_err(|_| EnvError::new(format!("the adapter's {what} returned non-bytes")))
}

/// The address of an observation destination, as the adapter's `address` argument. The
/// adapter writes at most the observation space's bytes there, during the call only.
pub(crate) fn address(obs: &mut [u8]) -> usize {
    obs.as_mut_ptr() as usize
}

impl HostedEnv {
    /// Keep the info bytes an adapter call returned (`None`: no info).
    fn keep_info(&mut self, b: &Bound<'_, PyAny>) -> Result<(), EnvError> {
        self.info.clear();
        if !b.is_none() {
            self.info.extend_from_slice(returned_bytes(b, "info")?);
        }
        Ok(())
    }

    /// Call `adapter.step(arg, address)` and unpack `(reward, terminated, truncated, info)`.
    fn step_with<'py>(
        &mut self,
        py: Python<'py>,
        arg: Bound<'py, PyAny>,
        obs: &mut [u8],
    ) -> Result<StepOutcome, EnvError> {
        self.after_step = false;
        let err = |e: PyErr| env_error(py, &self.encoded, e);
        let r = self
            .adapter
            .bind(py)
            .call_method1(intern!(py, "step"), (arg, address(obs)))
            .map_err(err)?;
        let t = r
            .cast::<PyTuple>()
            .map_err(|_| EnvError::new("the adapter's step returned a non-tuple"))?;
        let reward: f64 = t.get_item(0).and_then(|x| x.extract()).map_err(err)?;
        let terminated: bool = t.get_item(1).and_then(|x| x.extract()).map_err(err)?;
        let truncated: bool = t.get_item(2).and_then(|x| x.extract()).map_err(err)?;
        self.keep_info(&t.get_item(3).map_err(err)?)?;
        self.after_step = true;
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
        // A reset right after a step of the same command is its autoreset: the step's info
        // stays with the reset's.
        let fresh = !std::mem::take(&mut self.after_step);
        Python::attach(|py| {
            let r = self
                .adapter
                .bind(py)
                .call_method1(intern!(py, "reset"), (seed, episode, fresh, address(obs)))
                .map_err(|e| env_error(py, &self.encoded, e))?;
            self.keep_info(&r)
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

    fn extra_info(&mut self, out: &mut Vec<u8>) -> Result<(), EnvError> {
        self.after_step = false;
        out.append(&mut self.info);
        Ok(())
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
            self.adapter
                .bind(py)
                .call_method1(intern!(py, "observe"), (address(obs),))
                .map_err(|e| env_error(py, &self.encoded, e))?;
            Ok(())
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
