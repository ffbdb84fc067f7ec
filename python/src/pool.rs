//! `rogue_gym._native.Pool`: the environment pool (supervisor in this process, workers spawned
//! as `python -m rogue_gym.worker`), with zero-copy views of worker blocks for the async API.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use numpy::ndarray::ArrayView1;
use numpy::npyffi::flags::NPY_ARRAY_WRITEABLE;
use numpy::{
    PyArray1, PyArrayDescrMethods, PyArrayMethods, PyReadonlyArray1, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use rogue_gym_pool::{
    AutoresetMode, Batch, BatchOutput, Block, EnvRecord, EnvRegistry, FailurePolicy,
    InterruptCheck, Pool, PoolConfig, PoolError, SeedSchedule, WorkerCommand, WorkerFailure,
};
use rogue_gym_pool::{FLAG_FINAL_OBS, FLAG_RESTARTED, FLAG_TERMINATED, FLAG_TRUNCATED};
use serde::Deserialize;
use serde_json::Value;

/// Bytes of one [`EnvRecord`] (the Python side mirrors it as a structured dtype).
pub const RECORD_BYTES: usize = std::mem::size_of::<EnvRecord>();

/// The pool settings the Python package sends (JSON).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PyPoolSettings {
    env: Value,
    num_envs: usize,
    num_workers: usize,
    #[serde(default)]
    batch_size: Option<usize>,
    #[serde(default)]
    seeds: SeedSchedule,
    #[serde(default)]
    autoreset: AutoresetMode,
    #[serde(default)]
    on_worker_failure: FailurePolicy,
    #[serde(default)]
    step_timeout_s: Option<f64>,
    #[serde(default)]
    start_timeout_s: Option<f64>,
    #[serde(default)]
    max_restarts: Option<u32>,
    #[serde(default)]
    max_borrowed: Option<usize>,
    #[serde(default)]
    base_dir: Option<String>,
}

fn duration(what: &str, secs: f64) -> PyResult<Duration> {
    Duration::try_from_secs_f64(secs).map_err(|_| {
        PyValueError::new_err(format!(
            "{what} must be a non-negative number of seconds, got {secs}"
        ))
    })
}

/// Map a pool error to the matching Python exception (never a panic).
pub fn pool_error(py: Python<'_>, e: PoolError) -> PyErr {
    match e {
        PoolError::WorkerFailed(f) => crashed(py, &format!("{f}; call reset() to continue"), &f),
        PoolError::RestartBudgetExceeded { max_restarts, last } => crashed(
            py,
            &format!("restart budget exhausted ({max_restarts} restarts); last failure: {last}"),
            &last,
        ),
        e @ (PoolError::Config(_)
        | PoolError::Env(_)
        | PoolError::BadAction { .. }
        | PoolError::BadActionsLength { .. }
        | PoolError::BadBuffer { .. }) => PyValueError::new_err(e.to_string()),
        e => PyRuntimeError::new_err(e.to_string()),
    }
}

/// Build a `rogue_gym.errors.WorkerCrashedError` for a failure report.
fn crashed(py: Python<'_>, msg: &str, f: &WorkerFailure) -> PyErr {
    let build = || -> PyResult<PyErr> {
        let cls = py
            .import("rogue_gym.errors")?
            .getattr("WorkerCrashedError")?;
        let kw = PyDict::new(py);
        kw.set_item("env", f.env_ids.start)?;
        kw.set_item("envs", f.env_ids.clone().collect::<Vec<_>>())?;
        kw.set_item("worker", f.worker)?;
        kw.set_item("pid", f.pid)?;
        kw.set_item("signal", f.signal)?;
        kw.set_item("exit_code", f.exit_code)?;
        kw.set_item("stderr_tail", &f.stderr_tail)?;
        let err = cls.call((msg,), Some(&kw))?;
        Ok(PyErr::from_value(err))
    };
    build().unwrap_or_else(|e| e)
}

/// A raw mutable byte buffer handed to code running without the GIL.
struct RawBuf(*mut u8, usize);
// SAFETY: the buffer belongs to a numpy array the caller keeps alive for the whole call; the
// pointer is only dereferenced inside that call.
unsafe impl Send for RawBuf {}

impl RawBuf {
    /// # Safety
    /// The array behind the pointer must stay alive and unaliased while the slice is used.
    unsafe fn slice<'a>(&self) -> &'a mut [u8] {
        if self.1 == 0 {
            return &mut [];
        }
        unsafe { std::slice::from_raw_parts_mut(self.0, self.1) }
    }
}

/// The writable, C-contiguous bytes of a numpy array, checked against an expected size.
fn raw_bytes(arr: &Bound<'_, PyUntypedArray>, what: &str, expected: usize) -> PyResult<RawBuf> {
    if !arr.is_c_contiguous() {
        return Err(PyValueError::new_err(format!(
            "{what} must be C-contiguous"
        )));
    }
    let ptr = arr.as_array_ptr();
    // SAFETY: `ptr` is a live array object (we hold a reference to it).
    let (data, flags) = unsafe { ((*ptr).fields.data as *mut u8, (*ptr).fields.flags) };
    if flags & NPY_ARRAY_WRITEABLE == 0 {
        return Err(PyValueError::new_err(format!("{what} must be writeable")));
    }
    let nbytes = arr.len() * arr.dtype().itemsize();
    if nbytes != expected {
        return Err(PyValueError::new_err(format!(
            "{what} has {nbytes} bytes (shape {:?}, dtype {}), expected {expected}",
            arr.shape(),
            arr.dtype()
        )));
    }
    Ok(RawBuf(data, nbytes))
}

fn record_flags(out: &BatchOutput, r: usize) -> u32 {
    let mut f = 0;
    if out.terminated[r] {
        f |= FLAG_TERMINATED;
    }
    if out.truncated[r] {
        f |= FLAG_TRUNCATED;
    }
    if out.restarted[r] {
        f |= FLAG_RESTARTED;
    }
    if out.has_final_obs[r] {
        f |= FLAG_FINAL_OBS;
    }
    f
}

/// Write the rows of `out` as [`EnvRecord`]s at their env ids into `recs`.
fn write_records(out: &BatchOutput, n_info: usize, recs: &mut [u8]) {
    for (r, &env) in out.env_ids.iter().enumerate() {
        let mut rec = EnvRecord {
            reward: out.reward[r],
            flags: record_flags(out, r),
            episode_return: out.episode_return[r],
            episode: out.episode[r],
            seed: out.seed[r],
            episode_length: out.episode_length[r],
            ..Default::default()
        };
        rec.info[..n_info].copy_from_slice(&out.info[r * n_info..(r + 1) * n_info]);
        let dst = &mut recs[env * RECORD_BYTES..(env + 1) * RECORD_BYTES];
        // SAFETY: EnvRecord is #[repr(C)] plain data of exactly RECORD_BYTES bytes.
        let src = unsafe {
            std::slice::from_raw_parts((&rec as *const EnvRecord).cast::<u8>(), RECORD_BYTES)
        };
        dst.copy_from_slice(src);
    }
}

/// Copy the valid final observations of `out` to their env rows of `fin`.
fn write_final(out: &BatchOutput, obs_bytes: usize, fin: &mut [u8]) {
    if out.final_obs.is_empty() {
        return;
    }
    for (r, &env) in out.env_ids.iter().enumerate() {
        if out.has_final_obs[r] {
            fin[env * obs_bytes..(env + 1) * obs_bytes]
                .copy_from_slice(&out.final_obs[r * obs_bytes..(r + 1) * obs_bytes]);
        }
    }
}

/// Owner of one worker block (an iceoryx2 sample) behind zero-copy numpy views.
///
/// The views returned by `Pool.recv()` have this object as their base: the shared-memory
/// sample stays mapped and unchanged for as long as any view (or this object) lives, even after
/// the pool is closed. There is no way to release it early (a dangling view is impossible).
#[pyclass(module = "rogue_gym._native", name = "BlockHolder", frozen)]
pub struct BlockHolder {
    block: Mutex<Block>,
}

#[pymethods]
impl BlockHolder {
    /// The worker that produced the block.
    #[getter]
    fn worker(&self) -> usize {
        self.block.lock().map(|b| b.worker()).unwrap_or(usize::MAX)
    }
}

/// Owner of the pool's shared batch buffer (two observation slots written by the workers)
/// behind the zero-copy views returned by `Pool.shared_views()`. The mapping stays valid for
/// as long as a view (or this object) lives, even after the pool is closed.
#[pyclass(module = "rogue_gym._native", name = "SharedBatchHolder", frozen)]
pub struct SharedBatchHolder {
    _buffer: std::sync::Arc<rogue_gym_ipc::SharedBuffer>,
}

/// The environment pool: `num_envs` envs stepped by `num_workers` worker processes.
///
/// `Pool(settings_json, worker_command)`; `worker_command` is the program and its leading
/// arguments, e.g. `[sys.executable, "-m", "rogue_gym.worker"]`. Every method raises a Python
/// exception on failure (`ValueError` for bad input, `rogue_gym.WorkerCrashedError` for a
/// failed worker under policy "raise", `RuntimeError` otherwise).
#[pyclass(module = "rogue_gym._native", name = "Pool")]
pub struct PyPool {
    pool: Mutex<Option<Pool>>,
    out: Mutex<BatchOutput>,
    num_envs: usize,
    num_workers: usize,
    obs_bytes: usize,
    n_info: usize,
    obs_shape: Vec<usize>,
    dtype: &'static str,
    info_names: Vec<String>,
    /// Column buffers bound by `bind_columns` (one per shared batch slot): the arrays (kept
    /// alive here) and their data pointers.
    columns: Mutex<Vec<(Py<PyAny>, usize)>>,
    /// The exception raised by a signal handler during a wait (see `interrupt_check`).
    interrupted: Arc<Mutex<Option<PyErr>>>,
}

/// The pool's interrupt check: between the slices of a long wait (GIL released), re-acquire
/// the GIL briefly and run Python's signal handlers; an exception (KeyboardInterrupt from
/// Ctrl-C) is kept in `slot` and aborts the wait.
fn interrupt_check(slot: Arc<Mutex<Option<PyErr>>>) -> InterruptCheck {
    Box::new(move || {
        Python::attach(|py| match py.check_signals() {
            Ok(()) => false,
            Err(e) => {
                if let Ok(mut s) = slot.lock() {
                    *s = Some(e);
                }
                true
            }
        })
    })
}

/// The column layout of a `bind_columns` buffer: `(name, numpy dtype, byte offset, rows)`; each
/// column is `rows x num_envs` C-contiguous. Eight-byte columns come first (8-aligned).
fn column_layout(
    n: usize,
    n_info: usize,
) -> (Vec<(&'static str, &'static str, usize, usize)>, usize) {
    let cols: [(&'static str, &'static str, usize, usize); 11] = [
        ("reward", "float64", 8, 1),
        ("seed", "uint64", 8, 1),
        ("episode_index", "int64", 8, 1),
        ("episode_return", "float64", 8, 1),
        ("episode_length", "int64", 8, 1),
        ("info_int", "int64", 8, n_info),
        ("terminated", "bool", 1, 1),
        ("truncated", "bool", 1, 1),
        ("restarted", "bool", 1, 1),
        ("has_final_obs", "bool", 1, 1),
        ("info_bool", "bool", 1, n_info),
    ];
    let mut off = 0;
    let mut v = Vec::with_capacity(cols.len());
    for (name, dt, size, rows) in cols {
        v.push((name, dt, off, rows));
        off += size * rows * n;
    }
    (v, off)
}

/// Summary bit of `step_columns`: some env's worker was restarted.
const SUMMARY_RESTARTED: usize = 1 << 8;
/// Summary bit of `step_columns`: some env has a final observation (SAME_STEP).
const SUMMARY_FINAL: usize = 1 << 9;

/// Write the rows of `out` into a column buffer (see [`column_layout`]); returns the
/// `SUMMARY_*` bits.
///
/// # Safety
/// `base` must point to a live, 8-aligned, writable buffer of the layout's size.
unsafe fn write_columns(out: &BatchOutput, n: usize, n_info: usize, base: *mut u8) -> usize {
    let w = |col: usize| unsafe { base.cast::<u64>().add(col * n) };
    let b8 = 8 * n * (5 + n_info);
    let b = |col: usize| unsafe { base.add(b8 + col * n) };
    let mut summary = 0;
    for (r, &i) in out.env_ids.iter().enumerate() {
        if i >= n {
            continue;
        }
        unsafe {
            *w(0).add(i) = f64::from(out.reward[r]).to_bits();
            *w(1).add(i) = out.seed[r];
            *w(2).add(i) = out.episode[r];
            *w(3).add(i) = out.episode_return[r].to_bits();
            *w(4).add(i) = u64::from(out.episode_length[r]);
            for k in 0..n_info {
                let v = out.info[r * n_info + k];
                *w(5 + k).add(i) = (v as i64) as u64;
                *b(4 + k).add(i) = u8::from(v != 0.0);
            }
            *b(0).add(i) = u8::from(out.terminated[r]);
            *b(1).add(i) = u8::from(out.truncated[r]);
            *b(2).add(i) = u8::from(out.restarted[r]);
            *b(3).add(i) = u8::from(out.has_final_obs[r]);
        }
        if out.restarted[r] {
            summary |= SUMMARY_RESTARTED;
        }
        if out.has_final_obs[r] {
            summary |= SUMMARY_FINAL;
        }
    }
    summary
}

impl PyPool {
    fn with_pool<R: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut Pool, &mut BatchOutput) -> Result<R, PoolError> + Send,
    ) -> PyResult<R> {
        let res = py.detach(|| {
            let mut guard = self
                .pool
                .lock()
                .map_err(|_| PoolError::State("the pool lock is poisoned".into()))?;
            let pool = guard.as_mut().ok_or(PoolError::Closed)?;
            let mut out = self
                .out
                .lock()
                .map_err(|_| PoolError::State("the pool lock is poisoned".into()))?;
            f(pool, &mut out)
        });
        res.map_err(|e| match e {
            PoolError::Interrupted => self
                .interrupted
                .lock()
                .ok()
                .and_then(|mut s| s.take())
                .unwrap_or_else(|| pool_error(py, PoolError::Interrupted)),
            e => pool_error(py, e),
        })
    }

    fn fill_outputs(
        &self,
        py: Python<'_>,
        recs: &Bound<'_, PyUntypedArray>,
        fin: Option<&Bound<'_, PyUntypedArray>>,
    ) -> PyResult<()> {
        let recs = raw_bytes(recs, "record array", self.num_envs * RECORD_BYTES)?;
        let fin = fin
            .map(|f| {
                raw_bytes(
                    f,
                    "final observation buffer",
                    self.num_envs * self.obs_bytes,
                )
            })
            .transpose()?;
        let out = self
            .out
            .lock()
            .map_err(|_| PyRuntimeError::new_err("the pool lock is poisoned"))?;
        let _ = py;
        // SAFETY: both arrays are alive for this call and not otherwise borrowed by us.
        unsafe {
            write_records(&out, self.n_info, recs.slice());
            if let Some(f) = fin {
                write_final(&out, self.obs_bytes, f.slice());
            }
        }
        Ok(())
    }
}

fn actions_vec(actions: &Bound<'_, PyAny>) -> PyResult<Vec<i64>> {
    let arr: PyReadonlyArray1<'_, i64> = actions.extract().map_err(|_| {
        PyTypeError::new_err("actions must be a 1-D int64 numpy array (one action per env)")
    })?;
    Ok(arr
        .as_slice()
        .map(<[i64]>::to_vec)
        .unwrap_or_else(|_| arr.as_array().to_vec()))
}

#[pymethods]
impl PyPool {
    /// Start a pool (spawns the workers and waits until they are ready; GIL released).
    #[new]
    fn new(py: Python<'_>, settings_json: &str, worker_command: Vec<String>) -> PyResult<Self> {
        let s: PyPoolSettings = serde_json::from_str(settings_json)
            .map_err(|e| PyValueError::new_err(format!("invalid pool settings: {e}")))?;
        let (program, args) = worker_command
            .split_first()
            .ok_or_else(|| PyValueError::new_err("worker_command must name a program"))?;
        let worker = WorkerCommand {
            program: program.into(),
            args: args.to_vec(),
        };
        let mut cfg = PoolConfig::new(s.env, s.num_envs, s.num_workers, worker);
        cfg.batch_size = s.batch_size;
        cfg.seeds = s.seeds;
        cfg.autoreset = s.autoreset;
        cfg.on_worker_failure = s.on_worker_failure;
        cfg.step_timeout = s
            .step_timeout_s
            .map(|t| duration("step_timeout", t))
            .transpose()?;
        if let Some(t) = s.start_timeout_s {
            cfg.start_timeout = duration("start_timeout", t)?;
        }
        if let Some(m) = s.max_restarts {
            cfg.max_restarts = m;
        }
        if let Some(m) = s.max_borrowed {
            cfg.max_borrowed = m;
        }
        if let Some(d) = s.base_dir {
            cfg.base_dir = d.into();
        }
        let mut pool = py
            .detach(|| Pool::new(cfg, &EnvRegistry::with_defaults()))
            .map_err(|e| pool_error(py, e))?;
        let interrupted = Arc::new(Mutex::new(None));
        pool.set_interrupt_check(Some(interrupt_check(interrupted.clone())));
        let spec = pool.spec().clone();
        Ok(PyPool {
            num_envs: pool.num_envs(),
            num_workers: pool.num_workers(),
            obs_bytes: pool.obs_bytes(),
            n_info: spec.info_names.len(),
            obs_shape: spec.obs_shape.clone(),
            dtype: spec.dtype.numpy_name(),
            info_names: spec.info_names.clone(),
            columns: Mutex::new(Vec::new()),
            interrupted,
            pool: Mutex::new(Some(pool)),
            out: Mutex::new(BatchOutput::default()),
        })
    }

    /// Sync reset of every env: observations into `obs_out` (`num_envs x obs`, C-contiguous),
    /// records into `recs_out` (`num_envs` records).
    fn reset(
        &self,
        py: Python<'_>,
        obs_out: &Bound<'_, PyUntypedArray>,
        recs_out: &Bound<'_, PyUntypedArray>,
    ) -> PyResult<()> {
        let obs = raw_bytes(
            obs_out,
            "observation buffer",
            self.num_envs * self.obs_bytes,
        )?;
        // SAFETY: obs_out is alive for the call; the pool writes it while Python waits.
        self.with_pool(py, move |p, out| p.reset(unsafe { obs.slice() }, out))?;
        self.fill_outputs(py, recs_out, None)
    }

    /// Sync step: `actions` (int64, one per env); observations into `obs_out`, records into
    /// `recs_out` and (SAME_STEP) final observations into `final_out`.
    #[pyo3(signature = (actions, obs_out, recs_out, final_out = None))]
    fn step(
        &self,
        py: Python<'_>,
        actions: &Bound<'_, PyAny>,
        obs_out: &Bound<'_, PyUntypedArray>,
        recs_out: &Bound<'_, PyUntypedArray>,
        final_out: Option<&Bound<'_, PyUntypedArray>>,
    ) -> PyResult<()> {
        let acts = actions_vec(actions)?;
        let obs = raw_bytes(
            obs_out,
            "observation buffer",
            self.num_envs * self.obs_bytes,
        )?;
        // SAFETY: as in `reset`.
        self.with_pool(py, move |p, out| p.step(&acts, unsafe { obs.slice() }, out))?;
        self.fill_outputs(py, recs_out, final_out)
    }

    /// Sync reset straight into the next shared batch slot (no copy); records into `recs_out`.
    /// Returns the slot index (see `shared_views()`).
    fn reset_shared(
        &self,
        py: Python<'_>,
        recs_out: &Bound<'_, PyUntypedArray>,
    ) -> PyResult<usize> {
        let slot = self.with_pool(py, |p, out| p.reset_shared(out))?;
        self.fill_outputs(py, recs_out, None)?;
        Ok(slot)
    }

    /// Sync step straight into the next shared batch slot (no copy): `actions` (int64, one per
    /// env); records into `recs_out`, (SAME_STEP) final observations into `final_out`. Returns
    /// the slot index. Slots alternate: slot `s` stays unchanged until the second following
    /// `*_shared` call.
    #[pyo3(signature = (actions, recs_out, final_out = None))]
    fn step_shared(
        &self,
        py: Python<'_>,
        actions: &Bound<'_, PyAny>,
        recs_out: &Bound<'_, PyUntypedArray>,
        final_out: Option<&Bound<'_, PyUntypedArray>>,
    ) -> PyResult<usize> {
        let acts = actions_vec(actions)?;
        let slot = self.with_pool(py, move |p, out| p.step_shared(&acts, out))?;
        self.fill_outputs(py, recs_out, final_out)?;
        Ok(slot)
    }

    /// Partial sync reset (gymnasium `reset_mask`) straight into the next shared batch slot:
    /// envs with `mask[i]` start their next scheduled episode, the others keep their state and
    /// their current observation is written again. `mask`: bool array, one per env. Records of
    /// every env into `recs_out`. Returns the slot index. Needs a full reset first.
    fn reset_envs_shared(
        &self,
        py: Python<'_>,
        mask: &Bound<'_, PyAny>,
        recs_out: &Bound<'_, PyUntypedArray>,
    ) -> PyResult<usize> {
        let arr: PyReadonlyArray1<'_, bool> = mask.extract().map_err(|_| {
            PyValueError::new_err(format!(
                "reset_mask must be a 1-D bool numpy array of shape ({},)",
                self.num_envs
            ))
        })?;
        let m: Vec<bool> = arr.as_array().to_vec();
        if m.len() != self.num_envs {
            return Err(PyValueError::new_err(format!(
                "reset_mask must have shape ({},), got ({},)",
                self.num_envs,
                m.len()
            )));
        }
        let slot = self.with_pool(py, move |p, out| p.reset_envs(&m, out))?;
        self.fill_outputs(py, recs_out, None)?;
        Ok(slot)
    }

    /// The layout of a column buffer for `bind_columns`: `(list of (name, dtype, byte offset,
    /// rows), total bytes)`. Each column is `rows x num_envs`, C-contiguous.
    fn column_layout(&self) -> (Vec<(&'static str, &'static str, usize, usize)>, usize) {
        column_layout(self.num_envs, self.n_info)
    }

    /// Bind one preallocated column buffer per shared batch slot (writable, C-contiguous,
    /// 8-aligned uint8 arrays of `column_layout()[1]` bytes). The pool keeps references to
    /// them; `step_columns` rewrites the buffer of the slot it returns.
    fn bind_columns(&self, buffers: Vec<Bound<'_, PyUntypedArray>>) -> PyResult<()> {
        let (_, total) = column_layout(self.num_envs, self.n_info);
        let mut v = Vec::with_capacity(buffers.len());
        for b in &buffers {
            let raw = raw_bytes(b, "column buffer", total)?;
            if !(raw.0 as usize).is_multiple_of(8) {
                return Err(PyValueError::new_err(
                    "column buffers must be 8-byte aligned",
                ));
            }
            v.push((b.clone().into_any().unbind(), raw.0 as usize));
        }
        *self
            .columns
            .lock()
            .map_err(|_| PyRuntimeError::new_err("the pool lock is poisoned"))? = v;
        Ok(())
    }

    /// The sync step of the gymnasium facade in one call: like `step_shared` (`actions`: int64,
    /// one per env, range-checked here; records into `recs_out`; SAME_STEP final observations
    /// into `final_out`), and the per-env values decoded into the column buffer bound for the
    /// returned slot (rewards as float64, flags as bool, info values as int64 and bool).
    /// Returns `slot | summary` where bit 8 = some worker restarted, bit 9 = some final obs.
    #[pyo3(signature = (actions, recs_out, final_out = None))]
    fn step_columns(
        &self,
        py: Python<'_>,
        actions: &Bound<'_, PyAny>,
        recs_out: &Bound<'_, PyUntypedArray>,
        final_out: Option<&Bound<'_, PyUntypedArray>>,
    ) -> PyResult<usize> {
        let acts = actions_vec(actions)?;
        let slot = self.with_pool(py, move |p, out| p.step_shared(&acts, out))?;
        self.fill_outputs(py, recs_out, final_out)?;
        let cols = self
            .columns
            .lock()
            .map_err(|_| PyRuntimeError::new_err("the pool lock is poisoned"))?;
        let &(_, ptr) = cols.get(slot).ok_or_else(|| {
            PyRuntimeError::new_err("step_columns needs bind_columns() with one buffer per slot")
        })?;
        let out = self
            .out
            .lock()
            .map_err(|_| PyRuntimeError::new_err("the pool lock is poisoned"))?;
        // SAFETY: the buffer is kept alive by `cols` and was checked (size, alignment,
        // writeable) by `bind_columns`; we hold the GIL, so Python cannot touch it meanwhile.
        let summary = unsafe { write_columns(&out, self.num_envs, self.n_info, ptr as *mut u8) };
        Ok(slot | summary)
    }

    /// Zero-copy uint8 views of the shared batch slots (`num_envs x obs_bytes` bytes each), in
    /// slot order. Their base owns the mapping, so they stay valid after `close()`.
    fn shared_views<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let guard = self
            .pool
            .lock()
            .map_err(|_| PyRuntimeError::new_err("the pool lock is poisoned"))?;
        let pool = guard
            .as_ref()
            .ok_or_else(|| PyRuntimeError::new_err("the pool is closed"))?;
        let buffer = pool
            .shared_buffer()
            .ok_or_else(|| PyRuntimeError::new_err("the pool has no shared batch buffer"))?;
        let len = self.num_envs * self.obs_bytes;
        let list = PyList::empty(py);
        let mut slot = 0;
        loop {
            let ptr = pool.shared_obs_ptr(slot);
            if ptr.is_null() {
                break;
            }
            let holder = Bound::new(
                py,
                SharedBatchHolder {
                    _buffer: buffer.clone(),
                },
            )?;
            // SAFETY: the slot lies inside the mapping owned (via the Arc) by `holder`, the
            // array's base; workers write it only during a `*_shared` call.
            let view = unsafe { ArrayView1::from_shape_ptr(len, ptr) };
            let arr = unsafe { PyArray1::<u8>::borrow_from_array(&view, holder.into_any()) };
            list.append(arr)?;
            slot += 1;
        }
        Ok(list)
    }

    /// Replace the episode-seed schedule (JSON `{"base": .., "set": .., "policy": ..}`) and
    /// restart every env's episode count; call a reset next.
    fn set_seeds(&self, py: Python<'_>, seeds_json: &str) -> PyResult<()> {
        let seeds: SeedSchedule = serde_json::from_str(seeds_json)
            .map_err(|e| PyValueError::new_err(format!("invalid seed schedule: {e}")))?;
        self.with_pool(py, move |p, _| p.set_seeds(seeds))
    }

    /// Async: reset every env; collect the results with `recv()`.
    fn async_reset(&self, py: Python<'_>) -> PyResult<()> {
        self.with_pool(py, |p, _| p.async_reset())
    }

    /// Async: send `actions` (int64) to `env_ids` (whole worker blocks, each in order).
    fn send(
        &self,
        py: Python<'_>,
        actions: &Bound<'_, PyAny>,
        env_ids: Vec<usize>,
    ) -> PyResult<()> {
        let acts = actions_vec(actions)?;
        self.with_pool(py, move |p, _| p.send(&acts, &env_ids))
    }

    /// Async: wait for the next batch; returns a list of `(env_start, obs_bytes_view, records)`
    /// per worker block, in arrival order. `obs_bytes_view` is a read-only zero-copy uint8 view
    /// of the block's observations in shared memory (its base owns the sample); `records` are
    /// the block's records as bytes.
    fn recv<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let batch: Batch = self.with_pool(py, |p, _| p.recv())?;
        let list = PyList::empty(py);
        for block in batch.blocks {
            let start = block.env_ids().start;
            let n = block.env_ids().len();
            let mut recs = vec![0u8; n * RECORD_BYTES];
            for j in 0..n {
                let rec = block.record(j);
                // SAFETY: EnvRecord is #[repr(C)] plain data.
                let src = unsafe {
                    std::slice::from_raw_parts(
                        (&rec as *const EnvRecord).cast::<u8>(),
                        RECORD_BYTES,
                    )
                };
                recs[j * RECORD_BYTES..(j + 1) * RECORD_BYTES].copy_from_slice(src);
            }
            let (ptr, len) = {
                let o = block.obs();
                (o.as_ptr(), o.len())
            };
            let holder = Bound::new(
                py,
                BlockHolder {
                    block: Mutex::new(block),
                },
            )?;
            // SAFETY: the bytes live in the sample owned by `holder`, which becomes the array's
            // base, so they outlive the view; the sample is never written while held.
            let view = unsafe { ArrayView1::from_shape_ptr(len, ptr) };
            let arr = unsafe { PyArray1::<u8>::borrow_from_array(&view, holder.into_any()) };
            drop(arr.try_readwrite()?.make_nonwriteable());
            list.append((start, arr, PyBytes::new(py, &recs)))?;
        }
        Ok(list)
    }

    /// Current worker process ids (index = worker).
    fn worker_pids(&self) -> PyResult<Vec<u32>> {
        let guard = self
            .pool
            .lock()
            .map_err(|_| PyRuntimeError::new_err("the pool lock is poisoned"))?;
        Ok(guard.as_ref().map(Pool::worker_pids).unwrap_or_default())
    }

    /// Worker restarts so far.
    fn restarts(&self) -> PyResult<u32> {
        let guard = self
            .pool
            .lock()
            .map_err(|_| PyRuntimeError::new_err("the pool lock is poisoned"))?;
        Ok(guard.as_ref().map(Pool::restarts).unwrap_or(0))
    }

    /// The pool's name (the prefix of its shared-memory files).
    fn name(&self) -> PyResult<String> {
        let guard = self
            .pool
            .lock()
            .map_err(|_| PyRuntimeError::new_err("the pool lock is poisoned"))?;
        Ok(guard
            .as_ref()
            .map(|p| p.id().name().to_string())
            .unwrap_or_default())
    }

    /// Stop the workers and remove the pool's files (idempotent; GIL released).
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        let taken = {
            let mut guard = self
                .pool
                .lock()
                .map_err(|_| PyRuntimeError::new_err("the pool lock is poisoned"))?;
            guard.take()
        };
        if let Some(mut p) = taken {
            py.detach(move || p.close())
                .map_err(|e| pool_error(py, e))?;
        }
        Ok(())
    }

    /// Whether `close()` was called.
    #[getter]
    fn closed(&self) -> bool {
        self.pool.lock().map(|g| g.is_none()).unwrap_or(true)
    }

    /// Number of envs.
    #[getter]
    fn num_envs(&self) -> usize {
        self.num_envs
    }

    /// Number of worker processes.
    #[getter]
    fn num_workers(&self) -> usize {
        self.num_workers
    }

    /// Observation shape of one env.
    #[getter]
    fn obs_shape(&self) -> Vec<usize> {
        self.obs_shape.clone()
    }

    /// Observation dtype name (`uint8` or `float32`).
    #[getter]
    fn obs_dtype(&self) -> &'static str {
        self.dtype
    }

    /// Bytes of one observation.
    #[getter]
    fn obs_bytes(&self) -> usize {
        self.obs_bytes
    }

    /// Names of the env's info values (columns of the records' `info`).
    #[getter]
    fn info_names(&self) -> Vec<String> {
        self.info_names.clone()
    }
}
