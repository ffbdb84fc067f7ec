//! `rogue_gym._native.Pool`: the environment pool (supervisor in this process, workers spawned
//! as `python -m rogue_gym.worker`), with zero-copy views of worker blocks for the async API.

use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};

use numpy::ndarray::ArrayView1;
use numpy::{PyArray1, PyReadonlyArray1, PyUntypedArray};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList, PyTuple};
use rogue_gym_pool::{
    Actions, BatchOutput, EnvRecord, Pool, PoolError, Received, RecvWant, SeedSchedule,
};

use crate::clock::CallClock;
use crate::columns::{
    RECORD_BYTES, column_layout, raw_bytes, write_columns, write_final, write_records,
};
use crate::errors::pool_error;
use crate::gil::{interrupt_check, lock_gil_free};
use crate::holders::SharedBatchHolder;
use crate::settings;

/// What `take_extras` returns: `(rows, data, size, ends)` (see there).
type JoinedExtras<'py> = (Option<Vec<usize>>, Bound<'py, PyBytes>, usize, Vec<usize>);

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
    /// The workers' pids, readable without the pool's lock (during a call too).
    pids: Arc<[AtomicU32]>,
    num_envs: usize,
    num_workers: usize,
    batch_size: usize,
    obs_bytes: usize,
    /// Bytes of one raw action (hosted envs; 0: action indices).
    action_bytes: usize,
    n_info: usize,
    obs_shape: Vec<usize>,
    dtype: &'static str,
    info_names: Vec<String>,
    /// Column buffers bound by `bind_columns` (one per shared batch slot): the arrays (kept
    /// alive here) and their data pointers.
    columns: Mutex<Vec<(Py<PyAny>, usize)>>,
    /// The exception raised by a signal handler during a wait (see `interrupt_check`).
    interrupted: Arc<Mutex<Option<PyErr>>>,
    /// Time in and between calls (`stats()`).
    clock: CallClock,
}

impl PyPool {
    /// Decode the last call's records into the column buffer of `slot`; returns `slot |`
    /// the `SUMMARY_*` bits.
    fn decode_columns(&self, py: Python<'_>, slot: usize) -> PyResult<usize> {
        let cols = self
            .columns
            .lock()
            .map_err(|_| PyRuntimeError::new_err("the pool lock is poisoned"))?;
        let &(_, ptr) = cols.get(slot).ok_or_else(|| {
            PyRuntimeError::new_err("step_columns needs bind_columns() with one buffer per slot")
        })?;
        let out = lock_gil_free(py, &self.out)?;
        // SAFETY: the buffer is kept alive by `cols` and was checked (size, alignment,
        // writeable) by `bind_columns`; we hold the GIL, so Python cannot touch it meanwhile.
        let summary = unsafe { write_columns(&out, self.num_envs, self.n_info, ptr as *mut u8) };
        Ok(slot | summary)
    }

    /// Read something of the open pool (the type's default once it is closed).
    fn peek<R: Default>(&self, py: Python<'_>, f: impl FnOnce(&Pool) -> R) -> PyResult<R> {
        let guard = lock_gil_free(py, &self.pool)?;
        Ok(guard.as_ref().map(f).unwrap_or_default())
    }

    fn with_pool<R: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut Pool, &mut BatchOutput) -> Result<R, PoolError> + Send,
    ) -> PyResult<R> {
        let start = self.clock.begin();
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
        self.clock.end(start);
        res.map_err(|e| match e {
            PoolError::Interrupted => take_interrupt(py, &self.interrupted),
            e => pool_error(py, e),
        })
    }

    /// Write the last call's records into `recs` (if given) and its final observations into
    /// `fin` (if given).
    fn fill_outputs(
        &self,
        py: Python<'_>,
        recs: Option<&Bound<'_, PyUntypedArray>>,
        fin: Option<&Bound<'_, PyUntypedArray>>,
    ) -> PyResult<()> {
        let recs = recs
            .map(|r| raw_bytes(r, "record array", self.num_envs * RECORD_BYTES))
            .transpose()?;
        let fin = fin
            .map(|f| {
                raw_bytes(
                    f,
                    "final observation buffer",
                    self.num_envs * self.obs_bytes,
                )
            })
            .transpose()?;
        let out = lock_gil_free(py, &self.out)?;
        let _ = py;
        // SAFETY: both arrays are alive for this call and not otherwise borrowed by us.
        unsafe {
            if let Some(r) = recs {
                write_records(&out, self.n_info, r.slice());
            }
            if let Some(f) = fin {
                write_final(&out, self.obs_bytes, f.slice());
            }
        }
        Ok(())
    }
}

/// Actions as the caller passed them, owned so that the pool can use them without the GIL.
enum OwnedActions {
    /// One index per env (int64).
    Indices(Vec<i64>),
    /// `action_bytes` raw bytes per env (hosted envs).
    Bytes(Vec<u8>),
}

impl OwnedActions {
    fn as_actions(&self) -> Actions<'_> {
        match self {
            OwnedActions::Indices(a) => Actions::Indices(a),
            OwnedActions::Bytes(b) => Actions::Bytes(b),
        }
    }
}

impl PyPool {
    /// Read `rows` actions: a 1-D int64 array (one index per env), or for hosted envs whose
    /// actions are `action_bytes` raw bytes, a 1-D uint8 array of `rows x action_bytes`.
    fn owned_actions(&self, actions: &Bound<'_, PyAny>, rows: usize) -> PyResult<OwnedActions> {
        if self.action_bytes == 0 {
            let arr: PyReadonlyArray1<'_, i64> = actions.extract().map_err(|_| {
                PyTypeError::new_err("actions must be a 1-D int64 numpy array (one action per env)")
            })?;
            return Ok(OwnedActions::Indices(arr.as_array().to_vec()));
        }
        let arr: PyReadonlyArray1<'_, u8> = actions.extract().map_err(|_| {
            PyTypeError::new_err("this env's actions travel as raw bytes: pass a 1-D uint8 array")
        })?;
        let v = arr.as_array().to_vec();
        if v.len() != rows * self.action_bytes {
            return Err(PyValueError::new_err(format!(
                "raw actions have {} bytes, expected {} ({rows} actions of {} bytes)",
                v.len(),
                rows * self.action_bytes,
                self.action_bytes
            )));
        }
        Ok(OwnedActions::Bytes(v))
    }
}

/// The exception a signal handler raised during a wait (e.g. `KeyboardInterrupt`), or the
/// pool's own error when there is none.
fn take_interrupt(py: Python<'_>, slot: &Mutex<Option<PyErr>>) -> PyErr {
    slot.lock()
        .ok()
        .and_then(|mut s| s.take())
        .unwrap_or_else(|| pool_error(py, PoolError::Interrupted))
}

#[pymethods]
impl PyPool {
    /// Start a pool (spawns the workers and waits until they are ready; GIL released).
    #[new]
    fn new(py: Python<'_>, settings_json: &str, worker_command: Vec<String>) -> PyResult<Self> {
        let cfg = settings::pool_config(settings_json, worker_command)?;
        let interrupted = Arc::new(Mutex::new(None));
        // The signal check runs during the start-up too: Ctrl-C stops a slow one at once.
        let check = interrupt_check(interrupted.clone());
        let pool = py
            .detach(|| Pool::with_interrupt_check(cfg, &crate::registry(), Some(check)))
            .map_err(|e| match e {
                PoolError::Interrupted => take_interrupt(py, &interrupted),
                e => pool_error(py, e),
            })?;
        let spec = pool.spec().clone();
        let pids = pool.pids_handle();
        Ok(PyPool {
            pids,
            num_envs: pool.num_envs(),
            num_workers: pool.num_workers(),
            batch_size: pool.batch_size(),
            obs_bytes: pool.obs_bytes(),
            action_bytes: spec.action_bytes,
            n_info: spec.info_names.len(),
            obs_shape: spec.obs_shape.clone(),
            dtype: spec.dtype.numpy_name(),
            info_names: spec.info_names.clone(),
            columns: Mutex::new(Vec::new()),
            interrupted,
            clock: CallClock::new(),
            pool: Mutex::new(Some(pool)),
            out: Mutex::new(BatchOutput::default()),
        })
    }

    /// Sync step straight into the next shared batch slot (no copy): `actions` (int64, one per
    /// env, or raw uint8 bytes for hosted envs whose actions travel so); records into
    /// `recs_out` (if given), (SAME_STEP) final observations into `final_out`. Returns the
    /// slot index. Slots alternate: slot `s` stays unchanged until the second following
    /// `*_shared` call.
    #[pyo3(signature = (actions, recs_out = None, final_out = None))]
    fn step_shared(
        &self,
        py: Python<'_>,
        actions: &Bound<'_, PyAny>,
        recs_out: Option<&Bound<'_, PyUntypedArray>>,
        final_out: Option<&Bound<'_, PyUntypedArray>>,
    ) -> PyResult<usize> {
        let acts = self.owned_actions(actions, self.num_envs)?;
        let slot = self.with_pool(py, move |p, out| {
            p.step_shared_actions(acts.as_actions(), out)
        })?;
        self.fill_outputs(py, recs_out, final_out)?;
        Ok(slot)
    }

    /// The extra info of the last sync call's envs that wrote some (hosted envs: their info
    /// dicts as typed rows or pickles), joined: `(rows, data, size, ends)`. `rows`: the envs'
    /// ids in row order, or `None` when every env wrote some; `data`: their bytes, one after
    /// the other; `size`: the length of each when all have the same length and the same first
    /// `head` bytes, else 0; `ends`: where each one's bytes end in `data` (empty when `size`
    /// is not 0).
    fn take_extras<'py>(&self, py: Python<'py>, head: usize) -> PyResult<JoinedExtras<'py>> {
        let mut out = lock_gil_free(py, &self.out)?;
        let extras = std::mem::take(&mut out.extras);
        drop(out);
        let every = extras.len() == self.num_envs
            && extras.iter().enumerate().all(|(i, (env, _))| *env == i);
        let rows = (!every).then(|| extras.iter().map(|(env, _)| *env).collect());
        let size = match extras.first() {
            Some((_, first))
                if first.len() >= head
                    && extras
                        .iter()
                        .all(|(_, e)| e.len() == first.len() && e[..head] == first[..head]) =>
            {
                first.len()
            }
            _ => 0,
        };
        let total = extras.iter().map(|(_, e)| e.len()).sum();
        let data = PyBytes::new_with(py, total, |buf| {
            let mut at = 0;
            for (_, e) in &extras {
                buf[at..at + e.len()].copy_from_slice(e);
                at += e.len();
            }
            Ok(())
        })?;
        let ends = if size > 0 {
            Vec::new()
        } else {
            extras
                .iter()
                .scan(0, |at, (_, e)| {
                    *at += e.len();
                    Some(*at)
                })
                .collect()
        };
        Ok((rows, data, size, ends))
    }

    /// Partial sync reset (gymnasium `reset_mask`) straight into the next shared batch slot:
    /// envs with `mask[i]` start their next scheduled episode, the others keep their state and
    /// their current observation is written again. `mask`: bool array, one per env. Records of
    /// every env into `recs_out` (if given). Returns the slot index. Needs a full reset first.
    #[pyo3(signature = (mask, recs_out = None))]
    fn reset_envs_shared(
        &self,
        py: Python<'_>,
        mask: &Bound<'_, PyAny>,
        recs_out: Option<&Bound<'_, PyUntypedArray>>,
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
        let acts = self.owned_actions(actions, self.num_envs)?;
        let slot = self.with_pool(py, move |p, out| {
            p.step_shared_actions(acts.as_actions(), out)
        })?;
        self.fill_outputs(py, Some(recs_out), final_out)?;
        self.decode_columns(py, slot)
    }

    /// The first half of a sync step (gymnasium's `step_async`): check `actions` (int64 or
    /// raw action bytes, one per env) and send them; the workers step meanwhile. Returns the
    /// slot they write. Collect with `wait_shared` or `wait_columns`.
    fn step_shared_send(&self, py: Python<'_>, actions: &Bound<'_, PyAny>) -> PyResult<usize> {
        let acts = self.owned_actions(actions, self.num_envs)?;
        self.with_pool(py, move |p, _| p.send_step_shared(acts.as_actions()))
    }

    /// The first half of a full sync reset (gymnasium's `reset_async`); returns the slot.
    fn reset_shared_send(&self, py: Python<'_>) -> PyResult<usize> {
        self.with_pool(py, |p, _| p.send_reset_shared())
    }

    /// The second half of `step_shared_send`/`reset_shared_send`: wait at most `timeout`
    /// seconds (`None`: the call's own bound) for every worker; the slot, with the records and
    /// final observations written as `step_shared` writes them, or `None` when `timeout`
    /// passed first (the request stays pending: wait again).
    #[pyo3(signature = (timeout = None, recs_out = None, final_out = None))]
    fn wait_shared(
        &self,
        py: Python<'_>,
        timeout: Option<f64>,
        recs_out: Option<&Bound<'_, PyUntypedArray>>,
        final_out: Option<&Bound<'_, PyUntypedArray>>,
    ) -> PyResult<Option<usize>> {
        let timeout = timeout
            .map(|t| settings::duration("timeout", t))
            .transpose()?;
        let slot = self.with_pool(py, move |p, out| p.wait_shared(timeout, out))?;
        if slot.is_some() {
            self.fill_outputs(py, recs_out, final_out)?;
        }
        Ok(slot)
    }

    /// `wait_shared` for the native facade: the slot `| summary` with the values decoded into
    /// the slot's column buffer, as `step_columns` returns them; `None` on `timeout`.
    #[pyo3(signature = (timeout, recs_out, final_out = None))]
    fn wait_columns(
        &self,
        py: Python<'_>,
        timeout: Option<f64>,
        recs_out: &Bound<'_, PyUntypedArray>,
        final_out: Option<&Bound<'_, PyUntypedArray>>,
    ) -> PyResult<Option<usize>> {
        match self.wait_shared(py, timeout, Some(recs_out), final_out)? {
            Some(slot) => self.decode_columns(py, slot).map(Some),
            None => Ok(None),
        }
    }

    /// Zero-copy uint8 views of the shared batch slots (`num_envs x obs_bytes` bytes each), in
    /// slot order. Their base owns the mapping, so they stay valid after `close()`.
    fn shared_views<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let guard = lock_gil_free(py, &self.pool)?;
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

    /// Make the next `*_shared` call write batch slot `slot` (an index into
    /// `shared_views()`); the turns go on from there. `ValueError` for a slot that does not
    /// exist.
    fn select_slot(&self, py: Python<'_>, slot: usize) -> PyResult<()> {
        self.with_pool(py, move |p, _| p.select_slot(slot))
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

    /// Async: send `actions` (int64 indices, or raw uint8 bytes for hosted envs whose actions
    /// travel so) to `env_ids` (whole worker blocks, each in order).
    fn send(
        &self,
        py: Python<'_>,
        actions: &Bound<'_, PyAny>,
        env_ids: Vec<usize>,
    ) -> PyResult<()> {
        let acts = self.owned_actions(actions, env_ids.len())?;
        self.with_pool(py, move |p, _| p.send_actions(acts.as_actions(), &env_ids))
    }

    /// Async: the first envs ready, `(env_ids, obs, records, extras)`: int64 env ids, their
    /// observations as one uint8 array (`rows x obs_bytes`, a fresh copy), their records as
    /// bytes, and the `(env id, bytes)` of the envs that wrote extra info. `min_batch`,
    /// `max_batch` (default both `batch_size`) and `timeout` (seconds) as `RecvWant`: return
    /// once `max_batch` are ready, or at the deadline with at least `min_batch` (else
    /// `TimeoutError`, nothing lost).
    #[pyo3(signature = (min_batch=None, max_batch=None, timeout=None))]
    fn recv<'py>(
        &self,
        py: Python<'py>,
        min_batch: Option<usize>,
        max_batch: Option<usize>,
        timeout: Option<f64>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let timeout = timeout
            .map(|t| settings::duration("timeout", t))
            .transpose()?;
        let got: Received = self.with_pool(py, move |p, _| {
            let b = p.batch_size();
            let max = max_batch.unwrap_or(b).max(min_batch.unwrap_or(1));
            let min = min_batch.unwrap_or(max.min(b));
            p.recv_want(RecvWant {
                min_batch: min,
                max_batch: max,
                timeout,
            })
        })?;
        let mut recs = vec![0u8; got.records.len() * RECORD_BYTES];
        for (j, rec) in got.records.iter().enumerate() {
            // SAFETY: EnvRecord is #[repr(C)] plain data.
            let src = unsafe {
                std::slice::from_raw_parts((rec as *const EnvRecord).cast::<u8>(), RECORD_BYTES)
            };
            recs[j * RECORD_BYTES..(j + 1) * RECORD_BYTES].copy_from_slice(src);
        }
        let extras = PyList::empty(py);
        for (row, bytes) in &got.extras {
            extras.append((got.env_ids[*row], PyBytes::new(py, bytes)))?;
        }
        let ids: Vec<i64> = got.env_ids.iter().map(|&e| e as i64).collect();
        PyTuple::new(
            py,
            [
                PyArray1::from_vec(py, ids).into_any(),
                PyArray1::from_vec(py, got.obs).into_any(),
                PyBytes::new(py, &recs).into_any(),
                extras.into_any(),
            ],
        )
    }

    /// Call into envs off the hot path: `requests` are `(env id, request bytes)`; returns
    /// `(env id, reply bytes)` in the same order (GIL released while the workers answer).
    fn call_envs<'py>(
        &self,
        py: Python<'py>,
        requests: Vec<(usize, Vec<u8>)>,
    ) -> PyResult<Bound<'py, PyList>> {
        let replies = self.with_pool(py, move |p, _| p.call_envs(&requests))?;
        let list = PyList::empty(py);
        for (env, bytes) in replies {
            list.append((env, PyBytes::new(py, &bytes)))?;
        }
        Ok(list)
    }

    /// Stage the parts of no fixed size of the next step's actions, `(env id, bytes)` each: the
    /// next step command to each env's worker carries them, and the env takes them just before
    /// it steps (hosted envs: `set_action_extra`).
    fn stage_action_extras(&self, py: Python<'_>, extras: Vec<(usize, Vec<u8>)>) -> PyResult<()> {
        self.with_pool(py, move |p, _| p.stage_action_extras(&extras))
    }

    /// The envs worker `k` hosts, as `(start, end)` (contiguous blocks differing by at most one
    /// env, the larger first).
    fn worker_envs(&self, py: Python<'_>, k: usize) -> PyResult<(usize, usize)> {
        let guard = lock_gil_free(py, &self.pool)?;
        let r = guard.as_ref().map(|p| p.worker_envs(k)).unwrap_or(0..0);
        Ok((r.start, r.end))
    }

    /// Statistics since the pool started: `(workers, between_ns, inside_ns, calls)`, where
    /// `workers` is one dict per worker (its counters in shared memory, and what the
    /// supervisor counted of it) and the rest is the caller's clock: nanoseconds between and
    /// inside the pool's calls, and the calls made. Reads no worker message.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyList>, u64, u64, u64)> {
        let workers = self.peek(py, |p| p.stats())?;
        let list = PyList::empty(py);
        for w in workers {
            let d = PyDict::new(py);
            d.set_item("env_steps", w.env_steps)?;
            d.set_item("commands", w.commands)?;
            d.set_item("env_ns", w.env_ns)?;
            d.set_item("wait_ns", w.wait_ns)?;
            d.set_item("publish_ns", w.publish_ns)?;
            d.set_item("restarts", w.restarts)?;
            d.set_item("timeouts", w.timeouts)?;
            d.set_item("recycles", w.recycles)?;
            d.set_item("spilled_bytes", w.spilled_bytes)?;
            d.set_item("last_failure", w.last_failure)?;
            list.append(d)?;
        }
        let c = &self.clock;
        Ok((
            list,
            c.between_ns.load(Ordering::Relaxed),
            c.inside_ns.load(Ordering::Relaxed),
            c.calls.load(Ordering::Relaxed),
        ))
    }

    /// Current worker process ids (index = worker; 0 once closed). Readable from any thread,
    /// also while another one is inside a call.
    fn worker_pids(&self) -> PyResult<Vec<u32>> {
        Ok(self
            .pids
            .iter()
            .map(|p| p.load(Ordering::Relaxed))
            .collect())
    }

    /// Worker restarts so far.
    fn restarts(&self, py: Python<'_>) -> PyResult<u32> {
        self.peek(py, Pool::restarts)
    }

    /// The runtime directory that holds the pool's directories (`""` once closed).
    fn runtime_dir(&self, py: Python<'_>) -> PyResult<String> {
        self.peek(py, |p| p.id().base().display().to_string())
    }

    /// The pool's name (the prefix of its shared-memory files).
    fn name(&self, py: Python<'_>) -> PyResult<String> {
        self.peek(py, |p| p.id().name().to_string())
    }

    /// The envs whose worker was replaced by plan during the last call (recycling).
    fn recycled_envs(&self, py: Python<'_>) -> PyResult<Vec<usize>> {
        self.peek(py, |p| p.recycled_envs().to_vec())
    }

    /// Bytes the pool needs in /dev/shm (checked against its free space at creation).
    fn shm_bytes(&self, py: Python<'_>) -> PyResult<u64> {
        self.peek(py, |p| p.shm_bytes())
    }

    /// Stop the workers and remove the pool's files (idempotent; GIL released).
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        let taken = {
            let mut guard = lock_gil_free(py, &self.pool)?;
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
    fn closed(&self, py: Python<'_>) -> bool {
        lock_gil_free(py, &self.pool).map_or(true, |g| g.is_none())
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

    /// Envs an async `recv` returns by default.
    #[getter]
    fn batch_size(&self) -> usize {
        self.batch_size
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
