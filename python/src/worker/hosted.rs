//! The `"python"` env kind: a gymnasium env written in Python, hosted in a pool worker.
//!
//! The worker runs the pool's Rust loop with the GIL released; each call on a [`HostedEnv`]
//! takes the GIL. The adapter (`rogue_gym.worker.env_adapter.HostedEnv`) builds the env from the
//! caller's cloudpickled callable, resets it and answers calls; a step is the hot path, so it
//! runs here, with no Python frame of ours: the action's value (from the adapter's table or
//! decoder), `env.step`, the observation copied into the destination the worker lends (an
//! ndarray of the space's dtype and shape; anything else goes through the adapter's writer, by
//! address, during the call only), reward and flags read here, and the info encoded by the
//! adapter (typed rows or pickles) only when there is one. The env's JSON spec is
//! `{"kind": "python", "spec": <EnvSpec>, "adapter": {...}}`: the [`EnvSpec`] the front end
//! computed (the supervisor gets the same one), and what the adapter needs.
//!
//! A Python exception becomes an [`EnvError`] whose message is the adapter's encoding of it
//! (type, message, worker-side traceback), which the front end decodes to re-raise it.

use numpy::{PyArrayDescr, PyArrayDescrMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList, PyString, PyTuple, PyType};
use rogue_gym_pool::{Env, EnvError, EnvSpec, StepOutcome};
use serde_json::Value;

/// The kind name of hosted envs.
pub(crate) const KIND: &str = "python";
/// The Python module of the adapter.
const ADAPTER_MODULE: &str = "rogue_gym.worker.env_adapter";

/// One hosted env: its adapter object, what a step calls, and the spec the pool agreed on.
struct HostedEnv {
    adapter: Py<PyAny>,
    /// The adapter's exception class for encoded env exceptions.
    encoded: Py<PyAny>,
    /// The adapter module's `encode_exception` (an env's exception, for the caller).
    encode: Py<PyAny>,
    /// The env itself (its `step` is called from here).
    env: Py<PyAny>,
    /// How an action becomes the env's value.
    actions: Actions,
    /// The observation when it is one array: copied here from an ndarray of exactly this.
    obs_array: Option<ObsArray>,
    spec: EnvSpec,
    /// The info bytes of the current command, to hand over ([`Env::extra_info`]).
    info: Vec<u8>,
    /// The last call was a successful step: a reset now is its autoreset (same command).
    after_step: bool,
    /// That step's info, if it had one (the autoreset's info comes with it).
    step_info: Option<Py<PyAny>>,
    /// The layout of the last flat info of scalars, packed here while infos keep it.
    flat_info: Option<FlatInfo>,
}

/// A flat typed info layout (the adapter's `FlatPlan`): a step's info whose keys and value
/// types match is packed here, as the adapter would, without a Python call.
struct FlatInfo {
    keys: Vec<Py<PyString>>,
    types: Vec<Py<PyType>>,
    /// The row's header and structure.
    prefix: Vec<u8>,
    /// Each value's `struct` code (little-endian, standard sizes).
    codes: Vec<u8>,
}

/// A `FlatPlan` as it comes from Python: keys, value types, prefix, codes.
type PlanParts<'py> = (
    Vec<Bound<'py, PyString>>,
    Vec<Bound<'py, PyType>>,
    Vec<u8>,
    String,
);

/// The `struct` codes [`FlatInfo`] packs.
const FLAT_CODES: &[u8] = b"dfqQiIhHbB?";

impl FlatInfo {
    /// The plan the adapter returned, if it is one this packs.
    fn new(plan: &Bound<'_, PyAny>) -> Option<Self> {
        let (keys, types, prefix, codes): PlanParts<'_> = plan.extract().ok()?;
        let codes = codes.into_bytes();
        (keys.len() == codes.len()
            && types.len() == codes.len()
            && codes.iter().all(|c| FLAT_CODES.contains(c)))
        .then(|| Self {
            keys: keys.into_iter().map(Bound::unbind).collect(),
            types: types.into_iter().map(Bound::unbind).collect(),
            prefix,
            codes,
        })
    }

    /// Pack `info` into `out` (cleared first) if it has this layout's keys and value types
    /// and every value fits its code; `false` (the adapter decides) otherwise.
    fn pack(&self, py: Python<'_>, info: &Bound<'_, PyAny>, out: &mut Vec<u8>) -> bool {
        let Ok(dict) = info.cast_exact::<PyDict>() else {
            return false;
        };
        if dict.len() != self.codes.len() {
            return false;
        }
        out.clear();
        out.extend_from_slice(&self.prefix);
        for (i, (key, value)) in dict.iter().enumerate() {
            let want = self.keys[i].bind(py);
            if !(key.is(want) || key.eq(want).unwrap_or(false))
                || !value.get_type().is(self.types[i].bind(py))
                || pack_value(self.codes[i], &value, out).is_none()
            {
                out.clear();
                return false;
            }
        }
        true
    }
}

/// Append one value as `struct` packs it with `code` (little-endian); `None` if it does not
/// fit (the adapter then pickles the info, as `struct.error` makes it do).
fn pack_value(code: u8, value: &Bound<'_, PyAny>, out: &mut Vec<u8>) -> Option<()> {
    fn int<T: TryFrom<i64>>(value: &Bound<'_, PyAny>) -> Option<T> {
        T::try_from(value.extract::<i64>().ok()?).ok()
    }
    match code {
        b'd' => out.extend_from_slice(&value.extract::<f64>().ok()?.to_le_bytes()),
        b'f' => out.extend_from_slice(&(value.extract::<f64>().ok()? as f32).to_le_bytes()),
        b'q' => out.extend_from_slice(&value.extract::<i64>().ok()?.to_le_bytes()),
        b'Q' => out.extend_from_slice(&value.extract::<u64>().ok()?.to_le_bytes()),
        b'i' => out.extend_from_slice(&int::<i32>(value)?.to_le_bytes()),
        b'I' => out.extend_from_slice(&int::<u32>(value)?.to_le_bytes()),
        b'h' => out.extend_from_slice(&int::<i16>(value)?.to_le_bytes()),
        b'H' => out.extend_from_slice(&int::<u16>(value)?.to_le_bytes()),
        b'b' => out.extend_from_slice(&int::<i8>(value)?.to_le_bytes()),
        b'B' => out.extend_from_slice(&int::<u8>(value)?.to_le_bytes()),
        b'?' => out.push(u8::from(value.is_truthy().ok()?)),
        _ => return None,
    }
    Some(())
}

/// How an action becomes the value `env.step` takes.
enum Actions {
    /// A Discrete space's actions by index (a list).
    Table(Py<PyList>),
    /// A function of the action (its index or its bytes).
    Function(Py<PyAny>),
}

/// An observation space of one array: the dtype and shape an ndarray must have to be copied
/// here with one `memcpy`.
struct ObsArray {
    dtype: Py<PyArrayDescr>,
    shape: Vec<usize>,
    nbytes: usize,
}

/// An action as the pool hands it over.
enum Action<'a> {
    Index(usize),
    Bytes(&'a [u8]),
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
    let encoded = adapter_attr(py, "EncodedEnvError")?;
    let adapter = m
        .getattr(class)
        .and_then(|cls| cls.call_method1("build", args))
        .map_err(|e| env_error(py, &encoded, e))?
        .unbind();
    Ok((adapter, encoded))
}

/// An attribute of the adapter module.
fn adapter_attr(py: Python<'_>, name: &str) -> Result<Py<PyAny>, EnvError> {
    py.import(ADAPTER_MODULE)
        .and_then(|m| m.getattr(name))
        .map(Bound::unbind)
        .map_err(|e| EnvError::new(format!("{ADAPTER_MODULE}.{name}: {e}")))
}

/// The scope of a worker's env thread ([`rogue_gym_pool::ThreadScope`]): the thread attaches
/// to the interpreter once and detaches for its whole life, so that it keeps one Python thread
/// state. Without it each env call would make a thread state and free it, and the free unmaps
/// the state's frame stack: a TLB shootdown on every core the worker runs on, which measured
/// 14% of an env thread's time with 64 envs on threads.
pub(crate) fn thread_scope(body: &mut (dyn FnMut() + Send)) {
    Python::attach(|py| py.detach(body));
}

/// Build env number `index` of a pool (the [`rogue_gym_pool::EnvCtor`] of [`KIND`]).
pub(crate) fn make_hosted_env(v: &Value, index: u64) -> Result<Box<dyn Env>, EnvError> {
    let (spec, adapter_cfg) = spec_and_adapter(v)?;
    Python::attach(|py| {
        let (adapter, encoded) =
            build_adapter(py, ADAPTER_MODULE, "HostedEnv", (adapter_cfg, index))?;
        let parts = step_parts(py, &adapter)
            .map_err(|e| EnvError::new(format!("the adapter's step_parts: {e}")))?;
        let encode = adapter_attr(py, "encode_exception")?;
        let (env, actions, obs_array) = parts;
        Ok(Box::new(HostedEnv {
            adapter,
            encoded,
            encode,
            env,
            actions,
            obs_array,
            spec,
            info: Vec::new(),
            after_step: false,
            step_info: None,
            flat_info: None,
        }) as Box<dyn Env>)
    })
}

/// The adapter's `step_parts()` as it comes from Python: env, actions, dtype, shape.
type StepParts<'py> = (
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Option<Bound<'py, PyArrayDescr>>,
    Option<Vec<usize>>,
);

/// The adapter's `step_parts()`: the env, its actions and its observation array (if any).
fn step_parts(
    py: Python<'_>,
    adapter: &Py<PyAny>,
) -> PyResult<(Py<PyAny>, Actions, Option<ObsArray>)> {
    let parts = adapter.bind(py).call_method0("step_parts")?;
    let (env, actions, dtype, shape): StepParts<'_> = parts.extract()?;
    let actions = match actions.cast_into::<PyList>() {
        Ok(table) => Actions::Table(table.unbind()),
        Err(e) => Actions::Function(e.into_inner().unbind()),
    };
    let obs_array = match (dtype, shape) {
        (Some(dtype), Some(shape)) => Some(ObsArray {
            nbytes: shape.iter().product::<usize>() * dtype.itemsize(),
            dtype: dtype.unbind(),
            shape,
        }),
        _ => None,
    };
    Ok((env.unbind(), actions, obs_array))
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

    /// An env's exception (or one raised here on its bad output) as the adapter encodes it.
    fn raised(&self, py: Python<'_>, e: PyErr) -> EnvError {
        if e.get_type(py)
            .is_subclass(self.encoded.bind(py))
            .unwrap_or(false)
        {
            return env_error(py, &self.encoded, e);
        }
        let value = e.value(py);
        if let Some(tb) = e.traceback(py) {
            let _ = value.setattr(intern!(py, "__traceback__"), tb);
        }
        match self.encode.bind(py).call1((value,)) {
            Ok(s) => EnvError::new(s.to_string()),
            Err(_) => EnvError::new(e.to_string()),
        }
    }

    /// Step the env with `action` and write the observation into `obs`.
    fn step_with(
        &mut self,
        py: Python<'_>,
        action: Action<'_>,
        obs: &mut [u8],
    ) -> Result<StepOutcome, EnvError> {
        self.after_step = false;
        let out = self
            .step_env(py, action, obs)
            .map_err(|e| self.raised(py, e))?;
        self.after_step = true;
        Ok(out)
    }

    /// The step itself: an error is the env's own, or says what was wrong with its output.
    fn step_env(
        &mut self,
        py: Python<'_>,
        action: Action<'_>,
        obs: &mut [u8],
    ) -> PyResult<StepOutcome> {
        let value = match (&self.actions, action) {
            (Actions::Table(table), Action::Index(i)) => table.bind(py).get_item(i)?,
            (Actions::Function(f), Action::Index(i)) => f.bind(py).call1((i,))?,
            (Actions::Function(f), Action::Bytes(b)) => f.bind(py).call1((PyBytes::new(py, b),))?,
            (Actions::Table(_), Action::Bytes(_)) => {
                return Err(PyValueError::new_err(
                    "a Discrete action space takes action indices, not bytes",
                ));
            }
        };
        let r = self
            .env
            .bind(py)
            .call_method1(intern!(py, "step"), (value,))?;
        let t = r.cast_into::<PyTuple>().map_err(|_| {
            PyTypeError::new_err(
                "env.step() must return a tuple (obs, reward, terminated, truncated, info)",
            )
        })?;
        if t.len() != 5 {
            return Err(PyValueError::new_err(format!(
                "env.step() returned {} values; expected 5 (obs, reward, terminated, truncated, \
                 info)",
                t.len()
            )));
        }
        self.write_obs(py, &t.get_item(0)?, obs)?;
        let reward = t.get_item(1)?;
        let reward: f64 = reward.extract().map_err(|_| {
            PyTypeError::new_err(format!(
                "env.step() returned a reward of type {}; expected a number",
                reward
                    .get_type()
                    .name()
                    .map_or("?".into(), |n| n.to_string())
            ))
        })?;
        let terminated = t.get_item(2)?.is_truthy()?;
        let truncated = t.get_item(3)?.is_truthy()?;
        let info = t.get_item(4)?;
        self.info.clear();
        self.step_info = None;
        if info.is_truthy()? {
            self.encode_info(py, &info)?;
            self.step_info = Some(info.unbind());
        }
        Ok(StepOutcome {
            reward,
            terminated,
            truncated,
        })
    }

    /// Encode a step's info into [`HostedEnv::info`]: packed here when it has the last flat
    /// layout's keys and types, else by the adapter (which says when a new flat layout starts).
    fn encode_info(&mut self, py: Python<'_>, info: &Bound<'_, PyAny>) -> PyResult<()> {
        if let Some(flat) = &self.flat_info
            && flat.pack(py, info, &mut self.info)
        {
            return Ok(());
        }
        let r = self
            .adapter
            .bind(py)
            .call_method1(intern!(py, "step_info"), (info,))?;
        let (data, plan): (Bound<'_, PyAny>, Bound<'_, PyAny>) = r.extract()?;
        let data = data
            .cast::<PyBytes>()
            .map_err(|_| PyTypeError::new_err("the adapter's step_info returned non-bytes"))?;
        self.info.clear();
        self.info.extend_from_slice(data.as_bytes());
        if !plan.is_none() {
            self.flat_info = FlatInfo::new(&plan);
        }
        Ok(())
    }

    /// Write an observation into `dst`: one copy from an ndarray of exactly the space's dtype
    /// and shape, else through the adapter's writer (casts, reshapes, nested spaces).
    fn write_obs(&self, py: Python<'_>, o: &Bound<'_, PyAny>, dst: &mut [u8]) -> PyResult<()> {
        let adapter = self.adapter.bind(py);
        if let Some(a) = &self.obs_array
            && o.is_exact_instance_of::<PyUntypedArray>()
            && a.nbytes <= dst.len()
        {
            let arr = o.cast::<PyUntypedArray>()?;
            if arr.is_c_contiguous()
                && arr.shape() == a.shape.as_slice()
                && arr.dtype().is_equiv_to(a.dtype.bind(py))
            {
                if a.nbytes > 0 {
                    // SAFETY: a live C-contiguous array of `nbytes` bytes (its dtype and shape
                    // were checked); we hold the GIL, so nothing frees it during the copy.
                    let src = unsafe {
                        std::slice::from_raw_parts(
                            (*arr.as_array_ptr()).fields.data as *const u8,
                            a.nbytes,
                        )
                    };
                    dst[..a.nbytes].copy_from_slice(src);
                }
                return adapter.setattr(intern!(py, "_last"), o);
            }
        }
        adapter.call_method1(intern!(py, "write_obs"), (o, address(dst)))?;
        Ok(())
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
        // (if any) stays with the reset's.
        Python::attach(|py| {
            let after_step = std::mem::take(&mut self.after_step);
            let step_info = self.step_info.take().filter(|_| after_step);
            let r = self
                .adapter
                .bind(py)
                .call_method1(
                    intern!(py, "reset"),
                    (seed, episode, step_info, address(obs)),
                )
                .map_err(|e| env_error(py, &self.encoded, e))?;
            self.keep_info(&r)
        })
    }

    fn step(&mut self, action: usize, obs: &mut [u8]) -> Result<StepOutcome, EnvError> {
        Python::attach(|py| self.step_with(py, Action::Index(action), obs))
    }

    fn step_bytes(&mut self, action: &[u8], obs: &mut [u8]) -> Result<StepOutcome, EnvError> {
        Python::attach(|py| self.step_with(py, Action::Bytes(action), obs))
    }

    fn extra_info(&mut self, out: &mut Vec<u8>) -> Result<(), EnvError> {
        self.after_step = false;
        out.append(&mut self.info);
        Ok(())
    }

    fn set_action_extra(&mut self, extra: &[u8]) -> Result<(), EnvError> {
        Python::attach(|py| {
            self.adapter
                .bind(py)
                .call_method1(intern!(py, "set_action_extra"), (PyBytes::new(py, extra),))
                .map_err(|e| env_error(py, &self.encoded, e))?;
            Ok(())
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
