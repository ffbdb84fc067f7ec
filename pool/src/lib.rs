//! The Rogue-Gym environment pool: supervisor, worker loop and the [`Env`] trait.
//!
//! Its part in the whole: `engine` is the game, `ipc` the shared-memory transport (iceoryx2),
//! and this crate puts them together into a multi-process vector env. A [`Pool`] (the
//! supervisor, living in the trainer's process, e.g. behind the Python front end) spawns
//! `num_workers` worker processes with `std::process::Command`; each worker ([`worker_main`])
//! builds its block of envs (blocks differ by at most one env) from a JSON spec through an
//! [`EnvRegistry`] and steps them. Every per-env output of a whole-batch call (step, reset,
//! partial reset) is written by its worker in place, at the env's row of a shared batch slot
//! the call names (`batch_slots` of them, 2 by default; [`wire::slot_layout`]), where the
//! caller reads it ([`Pool::step`]; [`Pool::read_rows`] copies it out). The async API
//! ([`Pool::send`], [`Pool::recv`]) has every answer written in the slots too, each env's
//! answers taking turns over them; a batch of one run of envs in one slot can be handed over
//! as a view of it ([`Pool::set_async_views`]). A worker's iceoryx2 samples carry its answers'
//! words only.
//!
//! Modules, one job each:
//!
//! * [`config`]: [`PoolConfig`] and its enums; [`error`]: [`PoolError`], [`WorkerFailure`];
//!   [`batch`]: what a step returns.
//! * [`mod@env`]: the [`Env`] trait, [`EnvBlock`] (a worker's whole block behind one object, e.g.
//!   a hosted vector env) and [`EnvSpec`]; [`registry`]: kinds by name; [`kinds`]: the
//!   built-in kinds (the game, `"rogue"`, and a deterministic [`TestEnv`], `"test"`),
//!   registered here by [`EnvRegistry::with_defaults`].
//! * [`seeds`]: the [`SeedSchedule`]: the seed of env `i`'s `e`-th episode depends only on
//!   (schedule, `i`, `e`), never on worker count or timing.
//! * [`wire`]: the protocol both sides import; [`supervisor`]: the [`Pool`]; [`worker`]: the
//!   worker loop; [`stats`]: the counters workers keep in shared memory ([`Pool::stats`]).
//!
//! Crashes: dead (waitpid) or hung (`step_timeout`) workers are killed, cleaned up and
//! respawned; per [`FailurePolicy`] the affected envs report `truncated` + `restarted`, or the
//! call fails with [`PoolError::WorkerFailed`]. Cleanup: [`Pool::close`] (and `Drop`) removes
//! every `/dev/shm` file and directory of the pool; [`Pool::new`] sweeps pools left behind by
//! dead processes.

#![deny(missing_docs)]

pub mod batch;
pub mod config;
pub mod env;
pub mod error;
pub mod kinds;
pub mod registry;
pub mod seeds;
pub mod stats;
pub mod supervisor;
pub mod wire;
pub mod worker;

pub use batch::{BatchOutput, Received, SlotExtras};
pub use config::{AutoresetMode, CpuAffinity, FailurePolicy, PoolConfig, WorkerCommand};
pub use env::{
    Dtype, Env, EnvBlock, EnvError, EnvSpec, MAX_INFO, StepOutcome, action_out_of_range,
};
pub use error::{FailureCause, PoolError, WorkerFailure};
pub use kinds::test_env::TestEnv;
pub use registry::{BlockCtor, Built, EnvCtor, EnvRegistry, ThreadScope};
pub use rogue_gym_ipc::WaitPolicy;
pub use seeds::{SeedPolicy, SeedSchedule, SeedSet, Shard};
pub use stats::WorkerStats;
pub use supervisor::{Actions, InterruptCheck, MachineView, Pool, RecvWant, validate_actions};
pub use wire::answer::EXTRA_HEAD;
pub use wire::record::{
    EnvRecord, FLAG_FINAL_OBS, FLAG_RESTARTED, FLAG_TERMINATED, FLAG_TRUNCATED,
};
pub use wire::slot_layout::{COLUMNS, Column, ColumnView, SlotLayout, SlotRows};
pub use wire::{BATCH_SLOTS, EnvFault, MAX_BATCH_SLOTS, WorkerConfig};
pub use worker::worker_main;

impl EnvRegistry {
    /// The registry with every env kind of this crate: `"rogue"` (the Rogue-Gym game) and
    /// `"test"` (the deterministic [`TestEnv`]).
    pub fn with_defaults() -> Self {
        let mut r = Self::new();
        r.register("rogue", kinds::rogue::make_rogue_env);
        r.register("test", kinds::test_env::make_test_env);
        r
    }
}
