//! Pool errors as Python exceptions (never a panic across the FFI boundary).

use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rogue_gym_pool::{PoolError, WorkerFailure};

/// Map a pool error to the matching Python exception (never a panic).
pub(crate) fn pool_error(py: Python<'_>, e: PoolError) -> PyErr {
    match e {
        PoolError::WorkerFailed(f) => crashed(py, &format!("{f}; call reset() to continue"), &f),
        PoolError::RestartBudgetExceeded { max_restarts, last } => crashed(
            py,
            &format!("restart budget exhausted ({max_restarts} restarts); last failure: {last}"),
            &last,
        ),
        PoolError::EnvFailed { fault, worker, pid } => {
            let msg = format!(
                "env {} failed in {} (worker {worker}, pid {pid}): {}; call reset() to continue",
                fault.env, fault.context, fault.message
            );
            let build = || -> PyResult<PyErr> {
                let cls = py.import("rogue_gym.errors")?.getattr("EnvFailedError")?;
                let kw = PyDict::new(py);
                kw.set_item("env", fault.env)?;
                kw.set_item("worker", worker)?;
                kw.set_item("pid", pid)?;
                kw.set_item("context", &fault.context)?;
                kw.set_item("detail", &fault.message)?;
                Ok(PyErr::from_value(cls.call((msg,), Some(&kw))?))
            };
            build().unwrap_or_else(|e| e)
        }
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
