//! Shared-memory transport of one Rogue-Gym environment pool.
//!
//! This crate is the *transport only*: it knows nothing of games, observations or actions. The
//! pool crate (`rogue-gym-pool`) builds its supervisor and worker on top of it.
//!
//! What it provides, for one pool:
//! * **Naming** ([`PoolId`]): one short random prefix (`rg<12hex>_`) and one short root
//!   directory per pool, so several pools coexist and unix socket paths stay under 108 bytes.
//! * **Privacy** ([`private`]): every pool lives in the user's runtime directory
//!   ([`resolve_runtime_dir`], 0700, verified), and every file and directory it makes is
//!   created exclusively, without following links, closed to group and others.
//! * **Ports** ([`SupervisorPorts`], [`WorkerPorts`]): every iceoryx2 service is built by exactly
//!   one function per service kind ([`cmd_service`], [`block_service`], [`cmd_event_service`],
//!   [`block_event_service`]), so both sides always agree on the settings.
//!   Per worker `k` there is a command channel (supervisor → worker, `[u64]` words with a
//!   [`CmdHeader`]) and a block channel (worker → supervisor, `[u64]` words with a
//!   [`BlockHeader`]), plus an event service per worker for commands and one shared event
//!   service (event id = worker index) for blocks. Payloads are 8-byte aligned `u64` words; the
//!   pool decides what they mean.
//! * **Shared batch buffer** ([`SharedBuffer`]): a plain `/dev/shm/<prefix>...` mapping that
//!   workers can write observations into directly (the pool's copy-free sync path).
//! * **Room** ([`room`]): the size and free space of `/dev/shm`, checked against a pool's need
//!   before anything is created.
//! * **Waiting** ([`WaitPolicy`], [`hybrid_wait`]): yield-poll for a bounded budget, then block
//!   on an iceoryx2 event listener with a timeout. Never an unbounded spin.
//! * **Cleanup** ([`remove_pool_files`], [`sweep_stale_pools`], [`cleanup_dead_nodes`]):
//!   remove a pool's `/dev/shm` files and directories, including iceoryx2's leftover
//!   `*.global_mgmt` counter, and sweep pools whose owner process is dead.
//!
//! All nodes are created with `SignalHandlingMode::Disabled`: the pool may be hosted inside a
//! Python interpreter and must not take SIGINT away from it. All ports use
//! [`ipc_threadsafe::Service`], so supervisor-side ports and received samples are `Send`.
//!
//! One module per job: [`naming`], [`private`], [`pool_files`], [`services`] (headers and service builders), [`ports`],
//! [`buffer`], [`room`], [`wait`], [`cleanup`] and [`error`].

#![deny(missing_docs)]

pub mod buffer;
pub mod cleanup;
pub mod cores;
pub mod error;
pub mod ledger;
pub mod naming;
pub mod pool_files;
pub mod ports;
pub mod private;
pub mod room;
pub mod services;
#[cfg(test)]
mod tests;
pub mod wait;

use iceoryx2::prelude::ipc_threadsafe;
use iceoryx2::sample::Sample;
use iceoryx2::sample_mut::SampleMut;

pub use iceoryx2;

pub use buffer::SharedBuffer;
pub use cleanup::{cleanup_dead_nodes, remove_pool_files, sweep_stale_pools};
pub use cores::{Cores, cores, usable_cores};
pub use error::IpcError;
pub use naming::{PoolId, pool_shm_files, process_start_time};
pub use pool_files::{create_node_counter, verify_pool_files};
pub use ports::{
    BlockListener, CmdWaker, SupervisorPorts, WorkerPorts, words_as_bytes, words_as_bytes_mut,
};
pub use private::{RUNTIME_DIR_ENV, default_runtime_dir, resolve_runtime_dir};
pub use room::{ShmRoom, check_room, shm_room};
pub use services::{
    BlockHeader, ChannelSettings, CmdHeader, block_event_service, block_service, channels_bytes,
    cmd_event_service, cmd_service, monotonic_ns,
};
pub use wait::{WaitCall, WaitOutcome, WaitPolicy, hybrid_wait};

/// The iceoryx2 service flavour used by every port of a pool (thread-safe, so ports are `Send`).
pub type Svc = ipc_threadsafe::Service;

/// A received block of words: an owned handle on a shared-memory sample. It is `Send`; the
/// memory stays mapped and unmodified for as long as the value lives.
pub type BlockSample = Sample<Svc, [u64], BlockHeader>;

/// A loaned, writable block sample (worker side).
pub type BlockSampleMut = SampleMut<Svc, [u64], BlockHeader>;
