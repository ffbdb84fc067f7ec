//! Native module of the `rogue_gym` Python package: the engine (`Game`), the environment
//! pool (`Pool`, with zero-copy views of its shared batch slots), the XLA handlers of `xla()`
//! (`xla/`) and the worker entry point
//! (`worker_main`, run by `python -m rogue_gym.worker`), which also hosts gymnasium envs
//! written in Python (`worker/`).
//!
//! Every Rust error is mapped to a Python exception; nothing panics across the FFI boundary.

#![deny(missing_docs)]

use pyo3::prelude::*;

mod clock;
mod columns;
mod errors;
mod game;
mod gil;
mod holders;
mod machine;
mod pool;
mod settings;
mod spec;
mod summary;
mod worker;
mod xla;

/// Run a pool worker with the given arguments (everything after `python -m rogue_gym.worker`)
/// and return its exit code. The GIL is released for the worker's whole life.
#[pyfunction]
fn worker_main(py: Python<'_>, argv: Vec<String>) -> i32 {
    py.detach(|| rogue_gym_pool::worker_main(&argv, &registry()))
}

/// The envs `[start, end)` that part `k` of `parts` holds when `num_envs` envs are split into
/// contiguous blocks differing by at most one env: the pool's split of envs among workers, and
/// `rogue_gym.ray`'s among actors.
#[pyfunction]
fn block_range(num_envs: usize, parts: usize, k: usize) -> PyResult<(usize, usize)> {
    if parts == 0 || parts > num_envs || k >= parts {
        return Err(pyo3::exceptions::PyValueError::new_err(format!(
            "block_range needs 1 <= parts <= num_envs and k < parts, got num_envs={num_envs}, parts={parts}, k={k}"
        )));
    }
    let r = rogue_gym_pool::wire::block_range(num_envs, parts, k);
    Ok((r.start, r.end))
}

/// The runtime directory a pool started now would use by default (`$ROGUE_GYM_RUNTIME_DIR`,
/// else `$XDG_RUNTIME_DIR/rogue-gym`, else `/tmp/rogue-gym-<uid>`), not yet checked.
#[pyfunction]
fn default_runtime_dir() -> String {
    rogue_gym_ipc::default_runtime_dir().display().to_string()
}

/// The env kinds of this extension's pools: the pool crate's own, plus `"python"` (hosted
/// gymnasium envs, see [`worker::hosted`]) and `"python-vector"` (a hosted vector env per
/// worker, see [`worker::hosted_vector`]).
pub(crate) fn registry() -> rogue_gym_pool::EnvRegistry {
    let mut r = rogue_gym_pool::EnvRegistry::with_defaults();
    r.register(worker::hosted::KIND, worker::hosted::make_hosted_env);
    r.register_block(
        worker::hosted_vector::KIND,
        worker::hosted_vector::make_hosted_vector,
    );
    r.set_thread_scope(worker::hosted::thread_scope);
    r
}

/// The `rogue_gym._native` module.
///
/// Free-threading stance (`gil_used = false`, PyO3 0.30's default, said here on purpose): the
/// module relies on no GIL for its own safety, so a free-threaded CPython (3.14t, 3.15t: a
/// source build, `docs/platforms.md`) keeps the GIL off when it imports it. Reviewed against
/// PyO3's thread-safety guide, class by class: `Pool` keeps the native pool behind a mutex (one
/// call at a time; every call runs through `Pool::guarded`, so no panic poisons it) and its
/// other state in mutexes and atomics; `Game` is mutated only through `&mut self`, which
/// PyO3's borrow flag (atomic on free-threaded builds) gives one thread at a time, a second
/// thread getting `RuntimeError: Already borrowed`; `SharedBatchHolder` is frozen (an `Arc` of
/// the mapping). Module-level state (the XLA targets) is behind mutexes. Calls into Python
/// from Rust threads (a worker's env threads) attach a thread state of their own.
#[pymodule(gil_used = false)]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<game::PyGame>()?;
    m.add_class::<pool::PyPool>()?;
    m.add_class::<holders::SharedBatchHolder>()?;
    m.add_function(wrap_pyfunction!(game::action_from_key, m)?)?;
    m.add_function(wrap_pyfunction!(worker_main, m)?)?;
    m.add_function(wrap_pyfunction!(block_range, m)?)?;
    m.add_function(wrap_pyfunction!(default_runtime_dir, m)?)?;
    m.add_function(wrap_pyfunction!(machine::usable_cores, m)?)?;
    m.add_function(wrap_pyfunction!(machine::cpu_limits, m)?)?;
    m.add_function(wrap_pyfunction!(machine::live_pools, m)?)?;
    m.add_function(wrap_pyfunction!(summary::floor_summary, m)?)?;
    m.add_function(wrap_pyfunction!(xla::xla_handlers, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("ACTION_KEYS", rogue_gym_engine::ACTION_KEYS)?;
    m.add(
        "PAPER_CONFIG_JSON",
        rogue_gym_engine::GameConfig::paper().to_json(),
    )?;
    m.add_function(wrap_pyfunction!(spec::normalize_obs_spec, m)?)?;
    m.add("NUM_ACTIONS", rogue_gym_engine::NUM_ACTIONS)?;
    m.add("ENGINE_VERSION", rogue_gym_engine::ENGINE_VERSION)?;
    m.add("SUMMARY_RESTARTED", columns::SUMMARY_RESTARTED)?;
    m.add("SUMMARY_FINAL", columns::SUMMARY_FINAL)?;
    m.add("EXTRA_HEAD", rogue_gym_pool::EXTRA_HEAD)?;
    m.add(
        "BOOL_INFO_NAMES",
        rogue_gym_pool::kinds::rogue::ROGUE_BOOL_INFO.to_vec(),
    )?;
    Ok(())
}
