//! The machine for Python: the cores this process really has (`usable_cores`, `cpu_limits`),
//! the user's live pools (`live_pools`, from the ledger), and a pool's view of them
//! (`Pool.machine()`). Every default of the package that counts cores reads them here.

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rogue_gym_pool::MachineView;

/// The cores this process may use at once: its affinity mask, at most its cgroup's CPU quota
/// rounded up (v2 `cpu.max` or v1 `cpu.cfs_quota_us`), 1 or more.
#[pyfunction]
pub(crate) fn usable_cores() -> usize {
    rogue_gym_ipc::usable_cores()
}

/// `(affinity CPUs, cgroup quota in CPUs or None)`: what bounds the usable cores.
#[pyfunction]
pub(crate) fn cpu_limits() -> (usize, Option<f64>) {
    let c = rogue_gym_ipc::cores();
    (c.affinity, c.quota)
}

/// The user's live pools on this machine (the ledger in the runtime directory, default or
/// `runtime_dir`): one dict each (`pool`, `pid`, `workers`, `caller_polls`, `cores`). Entries
/// of pools whose process is gone are removed.
#[pyfunction]
#[pyo3(signature = (runtime_dir = None))]
pub(crate) fn live_pools<'py>(
    py: Python<'py>,
    runtime_dir: Option<String>,
) -> PyResult<Bound<'py, PyList>> {
    let dir = rogue_gym_ipc::resolve_runtime_dir(runtime_dir.as_deref().map(std::path::Path::new))
        .map_err(|e| crate::errors::pool_error(py, e.into()))?;
    let ledger = rogue_gym_ipc::ledger::Ledger::open(&dir)
        .map_err(|e| crate::errors::pool_error(py, e.into()))?;
    let list = PyList::empty(py);
    for e in ledger.read() {
        list.append(entry(
            py,
            &e.pool,
            e.pid,
            e.workers,
            e.caller_polls,
            &e.cores,
        )?)?;
    }
    Ok(list)
}

fn entry<'py>(
    py: Python<'py>,
    pool: &str,
    pid: u32,
    workers: usize,
    caller_polls: bool,
    cores: &[usize],
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("pool", pool)?;
    d.set_item("pid", pid)?;
    d.set_item("workers", workers)?;
    d.set_item("caller_polls", caller_polls)?;
    d.set_item("cores", cores.to_vec())?;
    Ok(d)
}

/// A pool's view of the machine as a dict: `cores`, `demand`, `worker_pace`,
/// `caller_polls`, and `others` (the other live pools, as `live_pools` gives them).
pub(crate) fn view_dict<'py>(py: Python<'py>, v: &MachineView) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("cores", v.cores)?;
    d.set_item("demand", v.demand)?;
    d.set_item("worker_pace", v.worker_pace)?;
    d.set_item("caller_polls", v.caller_polls)?;
    let others = PyList::empty(py);
    for (pool, pid, workers, polls, cores) in &v.others {
        others.append(entry(py, pool, *pid, *workers, *polls, cores)?)?;
    }
    d.set_item("others", others)?;
    Ok(d)
}
