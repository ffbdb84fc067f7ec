//! Pool errors as Python exceptions (never a panic across the FFI boundary).

use pyo3::exceptions::{PyOSError, PyPermissionError, PyRuntimeError, PyValueError};
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
        e @ PoolError::NotBackInTime { .. } => not_back_in_time(py, e),
        e @ PoolError::OutOfSharedMemory { .. } => {
            let msg = e.to_string();
            let PoolError::OutOfSharedMemory { failure, .. } = e else {
                unreachable!("matched above")
            };
            crashed(py, &msg, &failure)
        }
        e @ PoolError::Ipc(rogue_gym_ipc::IpcError::NoRoom { .. }) => {
            PyOSError::new_err((nix_enospc(), e.to_string()))
        }
        e @ PoolError::Ipc(rogue_gym_ipc::IpcError::NoMemory { .. }) => {
            PyOSError::new_err((ENOMEM, e.to_string()))
        }
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
        PoolError::Several(all) => several(py, all),
        PoolError::Closed => py
            .import("rogue_gym.errors")
            .and_then(|m| Ok((m.getattr("PoolClosedError")?, m.getattr("CLOSED_MESSAGE")?)))
            .and_then(|(cls, msg)| Ok(PyErr::from_value(cls.call1((msg,))?)))
            .unwrap_or_else(|e| e),
        e @ PoolError::RecvTimeout { .. } => {
            pyo3::exceptions::PyTimeoutError::new_err(e.to_string())
        }
        e @ PoolError::Ipc(rogue_gym_ipc::IpcError::Insecure { .. }) => {
            PyPermissionError::new_err(e.to_string())
        }
        e @ (PoolError::Config(_)
        | PoolError::Env(_)
        | PoolError::BadAction { .. }
        | PoolError::BadActionsLength { .. }
        | PoolError::BadBuffer { .. }) => PyValueError::new_err(e.to_string()),
        e => PyRuntimeError::new_err(e.to_string()),
    }
}

/// `ENOMEM`, the errno of no memory (an `OSError` with it reads as "Cannot allocate memory").
const ENOMEM: i32 = 12;

/// `ENOSPC`, the errno of a full filesystem (an `OSError` with it reads as "No space left").
fn nix_enospc() -> i32 {
    28
}

/// Several failures of one call: the first as its own exception, the others (as exceptions)
/// in its `others` attribute and, one line each, in its notes (shown by Python 3.11+).
fn several(py: Python<'_>, all: Vec<PoolError>) -> PyErr {
    let mut errs = all.into_iter().map(|e| pool_error(py, e));
    let Some(first) = errs.next() else {
        return PyRuntimeError::new_err("several failures (none recorded)");
    };
    let others: Vec<PyErr> = errs.collect();
    let attach = || -> PyResult<()> {
        let value = first.value(py);
        let notes: Vec<String> = others
            .iter()
            .map(|o| format!("also failed in the same call: {}", o.value(py)))
            .collect();
        let objs: Vec<Bound<'_, PyAny>> = others
            .iter()
            .map(|o| o.value(py).clone().into_any())
            .collect();
        value.setattr("others", objs)?;
        value.setattr("__notes__", notes)?;
        Ok(())
    };
    let _ = attach();
    first
}

/// A call that outlived its bound: a `WorkerCrashedError` naming the workers still coming
/// back (`restarting`), the deaths so far, and the last failure's details.
fn not_back_in_time(py: Python<'_>, e: PoolError) -> PyErr {
    let msg = e.to_string();
    let PoolError::NotBackInTime {
        waiting,
        deaths,
        last,
        ..
    } = e
    else {
        return PyRuntimeError::new_err(msg);
    };
    let restarting: Vec<usize> = waiting.iter().map(|(k, _)| *k).collect();
    crashed_kw(py, &msg, last.as_deref(), |kw| {
        if last.is_none() {
            kw.set_item("worker", restarting.first())?;
        }
        kw.set_item("restarting", restarting)?;
        kw.set_item("deaths", deaths)
    })
    .unwrap_or_else(|e| e)
}

/// Build a `rogue_gym.errors.WorkerCrashedError` for a failure report.
fn crashed(py: Python<'_>, msg: &str, f: &WorkerFailure) -> PyErr {
    crashed_kw(py, msg, Some(f), |_| Ok(())).unwrap_or_else(|e| e)
}

/// A `WorkerCrashedError` with the report's fields (if any) and the keywords `more` adds.
fn crashed_kw(
    py: Python<'_>,
    msg: &str,
    f: Option<&WorkerFailure>,
    more: impl FnOnce(&Bound<'_, PyDict>) -> PyResult<()>,
) -> PyResult<PyErr> {
    let cls = py
        .import("rogue_gym.errors")?
        .getattr("WorkerCrashedError")?;
    let kw = PyDict::new(py);
    if let Some(f) = f {
        kw.set_item("env", f.env_ids.start)?;
        kw.set_item("envs", f.env_ids.clone().collect::<Vec<_>>())?;
        kw.set_item("worker", f.worker)?;
        kw.set_item("pid", f.pid)?;
        kw.set_item("signal", f.signal)?;
        kw.set_item("exit_code", f.exit_code)?;
        kw.set_item("stderr_tail", &f.stderr_tail)?;
    }
    more(&kw)?;
    let err = cls.call((msg,), Some(&kw))?;
    Ok(PyErr::from_value(err))
}
