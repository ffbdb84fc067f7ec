//! The pool settings sent by the Python package (one JSON object whose keys are the Python
//! `rogue_gym.settings.PoolSettings` fields that reach Rust), turned into a [`PoolConfig`]. The
//! defaults live in Python; here every key is read as given.

use std::time::Duration;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rogue_gym_pool::{
    AutoresetMode, CpuAffinity, FailurePolicy, PoolConfig, SeedSchedule, WorkerCommand,
};
use serde::Deserialize;
use serde_json::Value;

/// The pool settings the Python package sends (JSON).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PyPoolSettings {
    env: Value,
    /// The env's spec when the Python side knows it (hosted envs).
    #[serde(default)]
    spec: Option<rogue_gym_pool::EnvSpec>,
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
    step_timeout: Option<f64>,
    #[serde(default)]
    start_timeout: Option<f64>,
    #[serde(default)]
    max_restarts: Option<u32>,
    /// Planned replacement of a worker after this many env steps.
    #[serde(default)]
    recycle_after_steps: Option<u64>,
    /// Planned replacement of a worker above this resident memory, bytes.
    #[serde(default)]
    recycle_above_rss: Option<u64>,
    /// Slots of the shared batch buffer (`None`: the pool's default, two).
    #[serde(default)]
    batch_slots: Option<usize>,
    /// Envs that stay together on one worker (see `PoolConfig::block_unit`).
    #[serde(default)]
    block_unit: Option<usize>,
    /// The runtime directory (`None`: the default, see `rogue_gym_ipc::default_runtime_dir`).
    #[serde(default)]
    runtime_dir: Option<String>,
    /// The supervisor's yield-poll budget before it blocks, µs.
    #[serde(default)]
    poll_us: Option<u64>,
    /// The workers' yield-poll budget before they block, µs.
    #[serde(default)]
    worker_poll_us: Option<u64>,
    /// Pin the workers (`PoolConfig::cpu_affinity`): a core offset, or `"disjoint"`.
    #[serde(default)]
    cpu_affinity: Option<AffinitySetting>,
    /// Observation rows written with streaming stores (`PoolConfig::streaming_stores`).
    #[serde(default)]
    streaming_stores: Option<bool>,
    /// A worker's misdeed, for the package's tests of what the caller checks
    /// (`PoolConfig::sabotage`); no public setting sends it.
    #[serde(default)]
    sabotage: Option<rogue_gym_pool::wire::sabotage::Sabotage>,
    /// Threads that step each worker's envs (`PoolConfig::env_threads`; 0: serial).
    #[serde(default)]
    env_threads: usize,
}

/// `cpu_affinity` as Python sends it.
#[derive(Debug, Deserialize)]
#[serde(untagged)]
enum AffinitySetting {
    Offset(usize),
    Named(String),
}

pub(crate) fn duration(what: &str, secs: f64) -> PyResult<Duration> {
    Duration::try_from_secs_f64(secs).map_err(|_| {
        PyValueError::new_err(format!(
            "{what} must be a non-negative number of seconds, got {secs}"
        ))
    })
}

/// The [`PoolConfig`] of a settings JSON object and a worker command (program, leading args).
pub(crate) fn pool_config(
    settings_json: &str,
    worker_command: Vec<String>,
) -> PyResult<PoolConfig> {
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
    cfg.spec = s.spec;
    cfg.seeds = s.seeds;
    cfg.autoreset = s.autoreset;
    cfg.on_worker_failure = s.on_worker_failure;
    cfg.step_timeout = s
        .step_timeout
        .map(|t| duration("step_timeout", t))
        .transpose()?;
    if let Some(t) = s.start_timeout {
        cfg.start_timeout = duration("start_timeout", t)?;
    }
    if let Some(m) = s.max_restarts {
        cfg.max_restarts = m;
    }
    cfg.recycle_after_steps = s.recycle_after_steps;
    cfg.recycle_above_rss = s.recycle_above_rss;
    if let Some(n) = s.batch_slots {
        cfg.batch_slots = n;
    }
    if let Some(u) = s.block_unit {
        cfg.block_unit = u;
    }
    cfg.runtime_dir = s.runtime_dir.map(Into::into);
    if let Some(us) = s.poll_us {
        cfg.wait.poll_budget = Duration::from_micros(us);
    }
    if let Some(us) = s.worker_poll_us {
        cfg.worker_wait.poll_budget = Duration::from_micros(us);
    }
    cfg.cpu_affinity = match s.cpu_affinity {
        None => None,
        Some(AffinitySetting::Offset(o)) => Some(CpuAffinity::Offset(o)),
        Some(AffinitySetting::Named(n)) if n == "disjoint" => Some(CpuAffinity::Disjoint),
        Some(AffinitySetting::Named(n)) => {
            return Err(PyValueError::new_err(format!(
                "cpu_affinity must be a core offset or \"disjoint\", got {n:?}"
            )));
        }
    };
    cfg.streaming_stores = s.streaming_stores;
    cfg.sabotage = s.sabotage;
    cfg.env_threads = s.env_threads;
    Ok(cfg)
}
