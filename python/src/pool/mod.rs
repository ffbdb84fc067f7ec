//! `rogue_gym._native.Pool`: the environment pool (supervisor in this process, workers spawned
//! as `python -m rogue_gym.worker`). One file per API, as the pool crate's supervisor is split:
//! [`sync_api`] (whole-batch steps and resets into shared batch slots), [`async_api`]
//! (EnvPool-style `send`/`recv`, env by env), [`env_calls`] (env operations off the hot path),
//! [`results`] (what every call's result shares: the `recv` columns, the joined extra info) and
//! [`actions`] (the caller's actions, owned for a call without the GIL); this file holds the
//! pool's life, statistics and introspection.

use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rogue_gym_pool::{Pool, PoolError};

use crate::clock::CallClock;
use crate::errors::pool_error;
use crate::gil::{interrupt_check, lock_gil_free};
use crate::settings;

mod actions;
mod async_api;
mod env_calls;
mod results;
mod sync_api;

#[pyclass(module = "rogue_gym._native", name = "Pool")]
pub struct PyPool {
    /// Shared (weakly) with the XLA handlers once `xla_key()` registered the pool.
    pool: Arc<Mutex<Option<Pool>>>,
    /// The pool's key among the XLA targets (`xla_key()`), once registered.
    xla_key: Mutex<Option<i32>>,
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
    /// The `recv` column buffer bound by `bind_recv_columns`: the array (kept alive here) and
    /// its data pointer.
    columns: Mutex<Option<(Py<PyAny>, usize)>>,
    /// The exception raised by a signal handler during a wait (see `interrupt_check`).
    interrupted: Arc<Mutex<Option<PyErr>>>,
    /// Time in and between calls (`stats()`).
    clock: CallClock,
}

impl PyPool {
    /// Read something of the open pool (the type's default once it is closed).
    fn peek<R: Default>(&self, py: Python<'_>, f: impl FnOnce(&Pool) -> R) -> PyResult<R> {
        let guard = lock_gil_free(py, &self.pool)?;
        Ok(guard.as_ref().map(f).unwrap_or_default())
    }

    /// Run a call of the pool with the GIL released ([`Pool::guarded`]: a panic in it is an
    /// error, never a poisoned lock).
    fn with_pool<R: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut Pool) -> Result<R, PoolError> + Send,
    ) -> PyResult<R> {
        let start = self.clock.begin();
        let res = py.detach(|| {
            let mut guard = crate::gil::lock_any(&self.pool);
            guard.as_mut().ok_or(PoolError::Closed)?.guarded(f)
        });
        self.clock.end(start);
        res.map_err(|e| match e {
            PoolError::Interrupted => take_interrupt(py, &self.interrupted),
            e => pool_error(py, e),
        })
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
            columns: Mutex::new(None),
            interrupted,
            clock: CallClock::new(),
            pool: Arc::new(Mutex::new(Some(pool))),
            xla_key: Mutex::new(None),
        })
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
            d.set_item("env_wait_ns", w.env_wait_ns)?;
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

    /// The machine as this pool sees it (`{}` once closed): its usable cores, the demand it
    /// counts, whether its workers block and its caller polls, the user's other live pools.
    fn machine<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let mut guard = lock_gil_free(py, &self.pool)?;
        match guard.as_mut() {
            Some(p) => crate::machine::view_dict(py, &p.machine()),
            None => Ok(PyDict::new(py)),
        }
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

    /// Bytes of the pool's own buffers (batch slots, episode books, counters): memory of the
    /// process, its pages reserved at creation.
    fn buffer_bytes(&self, py: Python<'_>) -> PyResult<u64> {
        self.peek(py, |p| p.buffer_bytes())
    }

    /// Register the pool with the XLA handlers (once) and return its key: the `handle` of
    /// `rogue_gym.xla`'s jitted functions. The handlers hold the pool weakly: after `close()`
    /// a compiled call fails with an error that says so.
    fn xla_key(&self, py: Python<'_>) -> PyResult<i32> {
        let mut key = lock_gil_free(py, &self.xla_key)?;
        if let Some(k) = *key {
            return Ok(k);
        }
        if self.closed(py) {
            return Err(pool_error(py, PoolError::Closed));
        }
        let k = crate::xla::register(crate::xla::XlaTarget::new(
            Arc::downgrade(&self.pool),
            self.num_envs,
            self.batch_size,
            self.obs_bytes,
            self.action_bytes,
            self.n_info,
        ));
        *key = Some(k);
        Ok(k)
    }

    /// Stop the workers and remove the pool's files (idempotent; GIL released).
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        if let Some(k) = lock_gil_free(py, &self.xla_key)?.take() {
            crate::xla::unregister(k);
        }
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
