//! The wire protocol between the supervisor and its workers, imported by both sides: one file
//! per message, its encoding and decoding together: commands (`command.rs`) and answers
//! ([`answer`]), the layout of a slot of the shared batch buffer ([`slot_layout`]), the per-env
//! record ([`record`]), the episode books (`books.rs`), the worker's config file
//! ([`WorkerConfig`]) and the files of env calls ([`calls`]).

pub mod answer;
pub(crate) mod books;
pub mod calls;
pub(crate) mod command;
pub mod record;
pub mod sabotage;
pub mod slot_layout;

use std::path::PathBuf;

use rogue_gym_ipc::ChannelSettings;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::config::{AutoresetMode, PoolConfig};
pub use crate::error::EnvFault;
use crate::seeds::SeedSchedule;
pub(crate) use command::{Command, Op, Pace, Serve};

/// Payload value of a reset ([`Op::Reset`]) for an env that is *not* reset (partial reset): the
/// env keeps its state and re-writes its current observation ([`crate::Env::observe`]).
pub(crate) const KEEP_EPISODE: u64 = u64::MAX;
/// Name of the shared batch buffer (`/dev/shm/<prefix>batch`).
pub(crate) const BATCH_BUFFER: &str = "batch";
/// Default number of slots of the shared batch buffer (double buffering).
pub const BATCH_SLOTS: usize = 2;
/// Most slots a shared batch buffer may have ([`crate::PoolConfig::batch_slots`]).
pub const MAX_BATCH_SLOTS: usize = 16;

/// The envs worker `k` of `num_workers` hosts: contiguous blocks, the first
/// `num_envs % num_workers` workers one env more than the rest (so any `num_envs >= num_workers`
/// works).
pub fn block_range(num_envs: usize, num_workers: usize, k: usize) -> std::ops::Range<usize> {
    let (q, r) = (num_envs / num_workers, num_envs % num_workers);
    let start = k * q + k.min(r);
    start..start + q + usize::from(k < r)
}

/// The envs worker `k` of `num_workers` hosts when envs come in groups of `unit` that must
/// stay on one worker (the agents of one multi-agent env): [`block_range`] over the groups.
pub fn block_range_of(
    num_envs: usize,
    num_workers: usize,
    k: usize,
    unit: usize,
) -> std::ops::Range<usize> {
    let unit = unit.max(1);
    let groups = block_range(num_envs / unit, num_workers, k);
    groups.start * unit..groups.end * unit
}

/// Words of the largest command to a worker of `envs` envs whose actions take `aw` words: an
/// action per env, and for a [`Command::subset`] command one word per env more.
pub(crate) fn command_words(envs: usize, aw: usize) -> usize {
    envs * (aw.max(1) + 1)
}

/// Bytes a pool needs in `/dev/shm` before it creates anything: its workers' channels
/// ([`rogue_gym_ipc::channels_bytes`]; `blocks`: each worker's envs, `aw`: action words per
/// env). Observations, records and infos are in the pool's own buffers ([`buffers_bytes`]),
/// not there.
pub(crate) fn shm_need(blocks: &[std::ops::Range<usize>], aw: usize) -> u64 {
    let workers: Vec<(usize, usize)> = blocks
        .iter()
        .map(|b| (command_words(b.len(), aw), answer::sample_words(b.len())))
        .collect();
    rogue_gym_ipc::channels_bytes(&workers)
}

/// Bytes of a pool's own buffers, reserved when they are made (not in `/dev/shm`:
/// [`rogue_gym_ipc::SharedBuffer`]): the batch buffer (every slot holds the rows of every env,
/// [`slot_layout::SlotLayout::bytes`]), the episode books and the workers' counters.
pub(crate) fn buffers_bytes(
    batch_slots: usize,
    slot: &slot_layout::SlotLayout,
    num_workers: usize,
) -> u64 {
    (batch_slots * slot.bytes()
        + books::books_bytes(slot.num_envs)
        + crate::stats::buffer_bytes(num_workers)) as u64
}

/// The order of the pool's buffers on a worker's command line (`--shared-fds`).
pub(crate) const SHARED_FDS: [&str; 3] = [
    BATCH_BUFFER,
    books::BOOKS_BUFFER,
    crate::stats::STATS_BUFFER,
];
/// The file a successor (a planned replacement of worker `index`, as generation `generation`)
/// creates once its envs are built: the supervisor then closes the worker it replaces.
pub(crate) fn successor_marker(
    id: &rogue_gym_ipc::PoolId,
    index: usize,
    generation: u64,
) -> PathBuf {
    id.aux_dir().join(format!("w{index}.g{generation}.built"))
}

/// The file the supervisor creates once the worker a successor replaces is gone: the
/// successor then opens the worker's ports and says it is ready.
pub(crate) fn successor_go(id: &rogue_gym_ipc::PoolId, index: usize, generation: u64) -> PathBuf {
    id.aux_dir().join(format!("w{index}.g{generation}.go"))
}

/// The file where worker `index` (generation `generation`) reports an env failure.
pub(crate) fn env_fault_path(id: &rogue_gym_ipc::PoolId, index: usize, generation: u64) -> PathBuf {
    id.aux_dir()
        .join(format!("w{index}.g{generation}.fault.json"))
}

/// Where worker `index` (generation `generation`), its envs on threads, reports the failure of
/// an env of a partial command, in its error answer number `answer`.
pub(crate) fn env_fault_path_of(
    id: &rogue_gym_ipc::PoolId,
    index: usize,
    generation: u64,
    answer: u64,
) -> PathBuf {
    id.aux_dir()
        .join(format!("w{index}.g{generation}.fault-{answer}.json"))
}

/// Where worker `index`, generation `generation`, puts the extra info of its answer `seq` that
/// did not fit the envs' rooms (entries in the [`calls::encode`] format, one per env flagged
/// [`record::FLAG_EXTRA_APART`]); the supervisor reads and removes it.
pub(crate) fn extra_apart_path(
    id: &rogue_gym_ipc::PoolId,
    index: usize,
    generation: u64,
    seq: u64,
) -> PathBuf {
    id.aux_dir()
        .join(format!("w{index}.g{generation}.extra-{seq}"))
}

/// Everything a worker needs, written by the supervisor to a private JSON file in the pool's
/// directory (inside the verified runtime directory, so no one else can swap it).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct WorkerConfig {
    /// Pool name (`rg<8hex>`).
    pub pool_name: String,
    /// The pool's runtime directory (verified private by the supervisor).
    pub runtime_dir: PathBuf,
    /// Envs of the whole pool.
    pub num_envs: usize,
    /// Workers of the pool.
    pub num_workers: usize,
    /// JSON spec of the env (see [`crate::EnvRegistry`]).
    pub env: Value,
    /// Episode seed schedule.
    pub seeds: SeedSchedule,
    /// Autoreset mode.
    pub autoreset: AutoresetMode,
    /// Yield-poll budget of the worker's wait, µs.
    pub poll_budget_us: u64,
    /// Longest blocking wait slice of the worker, ms (parent liveness is checked between).
    pub block_slice_ms: u64,
    /// Whether the worker's poll yields the CPU (see `WaitPolicy::yield_cpu`).
    #[serde(default = "default_true")]
    pub poll_yield: bool,
    /// Slots of the shared batch buffer ([`crate::PoolConfig::batch_slots`]).
    #[serde(default = "default_batch_slots")]
    pub batch_slots: usize,
    /// Envs that stay together on one worker ([`crate::PoolConfig::block_unit`]).
    #[serde(default = "default_block_unit")]
    pub block_unit: usize,
    /// The core worker `k` runs on, `cpu_cores[k]` ([`crate::PoolConfig::cpu_affinity`]);
    /// `None`: where the kernel puts it.
    #[serde(default)]
    pub cpu_cores: Option<Vec<usize>>,
    /// Observation rows written with streaming stores ([`crate::PoolConfig::streaming_stores`]).
    #[serde(default)]
    pub streaming_stores: Option<bool>,
    /// Threads that step a worker's envs ([`crate::PoolConfig::env_threads`]); 0: one after
    /// the other, on the worker's own thread.
    #[serde(default)]
    pub env_threads: usize,
    /// A worker's misdeed, for tests of the caller's checks ([`crate::PoolConfig::sabotage`]).
    #[serde(default)]
    pub sabotage: Option<sabotage::Sabotage>,
}

fn default_block_unit() -> usize {
    1
}

fn default_batch_slots() -> usize {
    BATCH_SLOTS
}

fn default_true() -> bool {
    true
}

impl WorkerConfig {
    /// What the workers of pool `pool_name` (in `runtime_dir`) are told of `cfg`; `cpu_cores`:
    /// the core of each worker, when the pool pins them.
    pub fn new(
        cfg: &PoolConfig,
        pool_name: &str,
        runtime_dir: PathBuf,
        cpu_cores: Option<Vec<usize>>,
    ) -> Self {
        WorkerConfig {
            pool_name: pool_name.to_string(),
            runtime_dir,
            num_envs: cfg.num_envs,
            num_workers: cfg.num_workers,
            env: cfg.env.clone(),
            seeds: cfg.seeds.clone(),
            autoreset: cfg.autoreset,
            poll_budget_us: cfg.worker_wait.poll_budget.as_micros() as u64,
            block_slice_ms: cfg.worker_wait.block_slice.as_millis() as u64,
            poll_yield: cfg.worker_wait.yield_cpu,
            batch_slots: cfg.batch_slots,
            block_unit: cfg.block_unit,
            cpu_cores,
            streaming_stores: cfg.streaming_stores,
            env_threads: cfg.env_threads,
            sabotage: cfg.sabotage.clone(),
        }
    }

    /// The envs worker `k` hosts ([`block_range_of`]).
    pub fn envs_of(&self, k: usize) -> std::ops::Range<usize> {
        block_range_of(self.num_envs, self.num_workers, k, self.block_unit)
    }
    /// The channel settings both sides use.
    pub fn channel_settings(&self) -> ChannelSettings {
        ChannelSettings {
            num_workers: self.num_workers,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::block_range;

    #[test]
    fn blocks_cover_every_env_once_and_differ_by_at_most_one() {
        for n in 1..40 {
            for w in 1..=n.min(9) {
                let blocks: Vec<_> = (0..w).map(|k| block_range(n, w, k)).collect();
                assert_eq!(blocks[0].start, 0);
                assert_eq!(blocks[w - 1].end, n);
                for unit in 1..=3 {
                    if n.is_multiple_of(unit) && w <= n / unit {
                        for k in 0..w {
                            let b = super::block_range_of(n, w, k, unit);
                            assert!(
                                b.start.is_multiple_of(unit) && b.end.is_multiple_of(unit),
                                "{n} {w} {unit}"
                            );
                        }
                    }
                }
                assert!(blocks.windows(2).all(|p| p[0].end == p[1].start));
                let sizes: Vec<usize> = blocks.iter().map(|b| b.len()).collect();
                assert!(sizes.iter().max().unwrap() - sizes.iter().min().unwrap() <= 1);
                assert!(
                    sizes.windows(2).all(|p| p[0] >= p[1]),
                    "larger blocks first"
                );
            }
        }
        assert_eq!(block_range(10, 4, 1), 3..6);
        assert_eq!(block_range(10, 4, 3), 8..10);
    }
}
