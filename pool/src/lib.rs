//! The Rogue-Gym environment pool: supervisor, worker loop and the [`Env`] trait.
//!
//! Its part in the whole: `engine` is the game, `ipc` the shared-memory transport (iceoryx2),
//! and this crate puts them together into a multi-process vector env. A [`Pool`] (the
//! supervisor, living in the trainer's process, e.g. behind the Python front end) spawns
//! `num_workers` worker processes with `std::process::Command`; each worker ([`worker_main`])
//! builds `num_envs / num_workers` envs from a JSON spec through an [`EnvRegistry`], steps them,
//! and writes observations straight into a loaned shared-memory block, which the supervisor
//! copies into the caller's batch buffer (sync [`Pool::step`]) or hands over zero-copy (async
//! [`Pool::recv`] returns [`Block`]s that own the samples). A third, copy-free sync form,
//! [`Pool::step_shared`], has the workers write straight into one of two pool-owned shared
//! batch slots (double buffering).
//!
//! * Envs: anything implementing [`Env`]; the Rogue-Gym game (`"rogue"` kind) and a
//!   deterministic [`TestEnv`] (`"test"`) are built in.
//! * Seeding: [`SeedSchedule`]: the seed of env `i`'s `e`-th episode depends only on
//!   (schedule, `i`, `e`), never on worker count or timing.
//! * Autoreset: [`AutoresetMode::NextStep`] (default) or [`AutoresetMode::SameStep`].
//! * Crashes: dead (waitpid) or hung (`step_timeout`) workers are killed, cleaned up and
//!   respawned; per [`FailurePolicy`] the affected envs report `truncated` + `restarted`, or the
//!   call fails with [`PoolError::WorkerFailed`].
//! * Cleanup: [`Pool::close`] (and `Drop`) removes every `/dev/shm` file and directory of the
//!   pool; [`Pool::new`] sweeps pools left behind by dead processes.

#![warn(missing_docs)]

pub mod env;
pub mod layout;
pub mod rogue;
pub mod seeds;
pub mod supervisor;
pub mod test_env;
pub mod worker;

pub use env::{Dtype, Env, EnvCtor, EnvError, EnvRegistry, EnvSpec, MAX_INFO, StepOutcome};
pub use layout::EnvRecord;
pub use rogue_gym_ipc::WaitPolicy;
pub use seeds::{SeedPolicy, SeedSchedule, SeedSet};
pub use supervisor::{
    Batch, BatchOutput, Block, FailureCause, FailurePolicy, InterruptCheck, Pool, PoolConfig,
    PoolError, WorkerCommand, WorkerFailure,
};
pub use test_env::TestEnv;
pub use worker::{AutoresetMode, BATCH_SLOTS, WorkerConfig, worker_main};
