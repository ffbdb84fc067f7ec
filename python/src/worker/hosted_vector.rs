//! The `"python-vector"` env kind: a gymnasium vector env (e.g. ale-py's C++ `AtariVectorEnv`)
//! hosting a worker's whole block of envs, stepped with one Python call per block instead of
//! one per env.
//!
//! The worker keeps the envs' episode bookkeeping ([`rogue_gym_pool::EnvBlock`]); each call
//! takes the GIL and calls the adapter (`rogue_gym.worker.vector_adapter.HostedVectorEnv`),
//! which writes the batch of observations straight into the worker's rows (by address, during
//! the call only) and returns rewards and flags as raw arrays and each env's info as bytes. The
//! JSON spec is `{"kind": "python-vector", "spec": <EnvSpec>, "adapter": {...}}`.

use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyList, PyTuple};
use rogue_gym_pool::{EnvBlock, EnvError, EnvSpec, StepOutcome};
use serde_json::Value;

use super::hosted::{address, build_adapter, env_error, returned_bytes, spec_and_adapter};

/// The kind name of hosted vector envs.
pub(crate) const KIND: &str = "python-vector";
/// The Python module of the adapter.
const ADAPTER_MODULE: &str = "rogue_gym.worker.vector_adapter";

/// One worker's hosted vector env.
struct HostedVector {
    adapter: Py<PyAny>,
    encoded: Py<PyAny>,
    spec: EnvSpec,
    /// Each env's info bytes of the current command ([`EnvBlock::extra_info`]).
    infos: Vec<Vec<u8>>,
}

/// Build the block of envs `envs` (the [`rogue_gym_pool::BlockCtor`] of [`KIND`]).
pub(crate) fn make_hosted_vector(
    v: &Value,
    envs: std::ops::Range<u64>,
) -> Result<Box<dyn EnvBlock>, EnvError> {
    let (spec, adapter_cfg) = spec_and_adapter(v)?;
    let n = (envs.end - envs.start) as usize;
    Python::attach(|py| {
        let (adapter, encoded) = build_adapter(
            py,
            ADAPTER_MODULE,
            "HostedVectorEnv",
            (adapter_cfg, envs.start, n),
        )?;
        Ok(Box::new(HostedVector {
            adapter,
            encoded,
            spec,
            infos: vec![Vec::new(); n],
        }) as Box<dyn EnvBlock>)
    })
}

/// `n` values of `N` bytes each from the raw bytes an adapter returned (`what` names them).
fn values<T, const N: usize>(
    b: &Bound<'_, PyAny>,
    n: usize,
    what: &str,
    read: impl Fn([u8; N]) -> T,
) -> Result<Vec<T>, EnvError> {
    let raw = returned_bytes(b, what)?;
    if raw.len() != n * N {
        return Err(EnvError::new(format!(
            "the adapter returned {} bytes of {what} for {n} envs of {N} bytes",
            raw.len()
        )));
    }
    let (chunks, _) = raw.as_chunks::<N>();
    Ok(chunks.iter().map(|c| read(*c)).collect())
}

impl HostedVector {
    /// Keep each env's info bytes from an adapter's list (`None`: no env has info).
    fn keep_infos(&mut self, b: &Bound<'_, PyAny>) -> Result<(), EnvError> {
        self.infos.iter_mut().for_each(Vec::clear);
        if b.is_none() {
            return Ok(());
        }
        let list = b
            .cast::<PyList>()
            .map_err(|_| EnvError::new("the adapter's infos are not a list"))?;
        for (slot, item) in self.infos.iter_mut().zip(list.iter()) {
            if !item.is_none() {
                slot.extend_from_slice(returned_bytes(&item, "info")?);
            }
        }
        Ok(())
    }
}

impl EnvBlock for HostedVector {
    fn spec(&self) -> EnvSpec {
        self.spec.clone()
    }

    fn reset(
        &mut self,
        mask: &[bool],
        seeds: &[u64],
        episodes: &[u64],
        obs: &mut [u8],
    ) -> Result<(), EnvError> {
        let mask: Vec<u8> = mask.iter().map(|&m| u8::from(m)).collect();
        Python::attach(|py| {
            let args = (
                PyBytes::new(py, &mask),
                PyBytes::new(py, rogue_gym_ipc::words_as_bytes(seeds)),
                PyBytes::new(py, rogue_gym_ipc::words_as_bytes(episodes)),
                address(obs),
            );
            let r = self
                .adapter
                .bind(py)
                .call_method1(intern!(py, "reset"), args)
                .map_err(|e| env_error(py, &self.encoded, e))?;
            self.keep_infos(&r)
        })
    }

    fn step(
        &mut self,
        actions: &[u64],
        obs: &mut [u8],
        fin: &mut [u8],
        out: &mut [StepOutcome],
    ) -> Result<(), EnvError> {
        let n = out.len();
        // 0: no final observations (NEXT_STEP).
        let fin = if fin.is_empty() { 0 } else { address(fin) };
        Python::attach(|py| {
            let arg = PyBytes::new(py, rogue_gym_ipc::words_as_bytes(actions));
            let err = |e: PyErr| env_error(py, &self.encoded, e);
            let r = self
                .adapter
                .bind(py)
                .call_method1(intern!(py, "step"), (arg, address(obs), fin))
                .map_err(err)?;
            let t = r
                .cast::<PyTuple>()
                .map_err(|_| EnvError::new("the adapter's step returned a non-tuple"))?;
            let item = |i| t.get_item(i).map_err(err);
            let rewards = values(&item(0)?, n, "rewards", f64::from_ne_bytes)?;
            let terminated = values(&item(1)?, n, "terminations", |[b]: [u8; 1]| b != 0)?;
            let truncated = values(&item(2)?, n, "truncations", |[b]: [u8; 1]| b != 0)?;
            for (j, o) in out.iter_mut().enumerate() {
                *o = StepOutcome {
                    reward: rewards[j],
                    terminated: terminated[j],
                    truncated: truncated[j],
                };
            }
            self.keep_infos(&item(3)?)
        })
    }

    fn extra_info(&mut self, j: usize, out: &mut Vec<u8>) -> Result<(), EnvError> {
        if let Some(info) = self.infos.get_mut(j) {
            out.append(info);
        }
        Ok(())
    }

    fn call(&mut self, j: usize, request: &[u8]) -> Result<Vec<u8>, EnvError> {
        let mut replies = self.calls(&[(j, request)])?;
        replies
            .pop()
            .ok_or_else(|| EnvError::new("no reply to a call"))
    }

    /// The whole request at once: the adapter runs an operation asked of every env once
    /// (`HostedVectorEnv.call_block`).
    fn calls(&mut self, requests: &[(usize, &[u8])]) -> Result<Vec<Vec<u8>>, EnvError> {
        Python::attach(|py| {
            let rows: Vec<usize> = requests.iter().map(|(j, _)| *j).collect();
            let bytes: Vec<Bound<'_, PyBytes>> =
                requests.iter().map(|(_, r)| PyBytes::new(py, r)).collect();
            let got = self
                .adapter
                .bind(py)
                .call_method1(intern!(py, "call_block"), (rows, bytes))
                .map_err(|e| env_error(py, &self.encoded, e))?;
            let list = got
                .cast::<pyo3::types::PyList>()
                .map_err(|_| EnvError::new("call_block returned no list"))?;
            list.iter()
                .map(|b| Ok(returned_bytes(&b, "call")?.to_vec()))
                .collect()
        })
    }
}

impl Drop for HostedVector {
    /// Close the vector env when the worker lets go of it (at exit).
    fn drop(&mut self) {
        Python::attach(|py| {
            let _ = self.adapter.bind(py).call_method0("close");
        });
    }
}
