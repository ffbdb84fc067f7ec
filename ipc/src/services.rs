//! Headers and service settings: every iceoryx2 service of a pool is built by exactly one
//! function per service kind, so both sides always agree on the settings.

use iceoryx2::prelude::*;

use crate::Svc;
use crate::error::IpcError;
use crate::error::ice;

/// Header of a command (supervisor → worker). The payload's meaning depends on `kind`, which the
/// pool defines.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[repr(C)]
pub struct CmdHeader {
    /// Sequence number of the command for this worker (echoed in the reply's [`BlockHeader`]).
    pub seq: u64,
    /// Command kind (defined by the pool).
    pub kind: u32,
    /// Number of meaningful payload words.
    pub len: u32,
}

/// Header of a block (worker → supervisor).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[repr(C)]
pub struct BlockHeader {
    /// Sequence number of the command this block answers (0 for the start-up message).
    pub seq: u64,
    /// Incarnation of the worker (incremented at each respawn), to drop stale blocks.
    pub generation: u64,
    /// Index of the worker that sent the block.
    pub worker: u32,
    /// Block kind (defined by the pool).
    pub kind: u32,
    /// When the block was published ([`monotonic_ns`], stamped by `send_block`): blocks that
    /// arrive together are served in the order they became ready.
    pub ready_ns: u64,
}

/// The machine's monotonic clock (`CLOCK_MONOTONIC`, the same in every process), in ns.
pub fn monotonic_ns() -> u64 {
    nix::time::clock_gettime(nix::time::ClockId::CLOCK_MONOTONIC)
        .map(|t| t.tv_sec() as u64 * 1_000_000_000 + t.tv_nsec() as u64)
        .unwrap_or(0)
}

/// Settings that both sides of a pool must agree on (pass them to the worker unchanged).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChannelSettings {
    /// Number of workers of the pool (event ids `0..num_workers`).
    pub num_workers: usize,
}

/// Samples of one worker the supervisor holds at once: the answer it has taken and not yet
/// read, and the next. A sample carries answer words only (the rows are in the pool's batch
/// slots), so nothing a caller keeps pins one.
pub const SAMPLES_HELD: usize = 2;
/// Commands a worker may have unread (a worker whose envs run on threads takes several).
const CMD_BUFFER: usize = 8;
/// Answers a worker may have untaken.
const ANSWER_BUFFER: usize = 4;

/// The page tmpfs charges a file by.
const PAGE: u64 = 4096;
/// What iceoryx2 adds to a data segment per sample (its header and the user header) and once
/// per segment: measured on iceoryx2's files (`tests/python/test_shm.py` compares the whole
/// with a running pool's files).
const SAMPLE_OVERHEAD: u64 = 32;
const SEGMENT_OVERHEAD: u64 = 520;
/// Pages of a worker's other files (two connections, three service records, one event
/// record), and of the pool's own (the node's records).
const WORKER_PAGES: u64 = 6;
const POOL_PAGES: u64 = 2;

/// Bytes of `/dev/shm` a pool's channels map, each file in whole pages (what tmpfs charges
/// once it is touched): `workers` holds each worker's largest command and largest answer, in
/// words. A publisher's segment holds every sample that can be in flight at once: the
/// subscriber's buffer, those it holds, and the one being loaned.
pub fn channels_bytes(workers: &[(usize, usize)]) -> u64 {
    let pages = |bytes: u64| bytes.div_ceil(PAGE) * PAGE;
    let segment = |samples: usize, words: usize| {
        pages(samples as u64 * (8 * words.max(1) as u64 + SAMPLE_OVERHEAD) + SEGMENT_OVERHEAD)
    };
    let per_worker: u64 = workers
        .iter()
        .map(|&(cmd, answer)| {
            segment(CMD_BUFFER + 2, cmd)
                + segment(ANSWER_BUFFER + SAMPLES_HELD + 1, answer)
                + WORKER_PAGES * PAGE
        })
        .sum();
    // The answers' event service, shared: its record grows with the workers it serves.
    let events = pages(320 * workers.len() as u64 + 1287);
    per_worker + events + POOL_PAGES * PAGE
}

impl ChannelSettings {
    fn max_event_ports(&self) -> usize {
        // Dead notifiers of crashed workers may linger until cleanup: leave room.
        2 * self.num_workers + 4
    }
}

/// Publish-subscribe service of a worker's commands.
pub fn cmd_service(
    node: &Node<Svc>,
    worker: usize,
) -> Result<
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, [u64], CmdHeader>,
    IpcError,
> {
    let name = format!("w{worker}c");
    let sn =
        ServiceName::new(&name).map_err(|e| IpcError::InvalidName(format!("{name}: {e:?}")))?;
    node.service_builder(&sn)
        .publish_subscribe::<[u64]>()
        .user_header::<CmdHeader>()
        .max_publishers(1)
        .max_subscribers(1)
        .max_nodes(4)
        .history_size(0)
        // Commands of a worker whose envs run on threads may queue (several in flight).
        .subscriber_max_buffer_size(CMD_BUFFER)
        .subscriber_max_borrowed_samples(1)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(ice(format!("open command service {name}")))
}

/// Publish-subscribe service of a worker's answers (their words; the rows are in the batch
/// slots).
pub fn block_service(
    node: &Node<Svc>,
    worker: usize,
) -> Result<
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, [u64], BlockHeader>,
    IpcError,
> {
    let name = format!("w{worker}b");
    let sn =
        ServiceName::new(&name).map_err(|e| IpcError::InvalidName(format!("{name}: {e:?}")))?;
    node.service_builder(&sn)
        .publish_subscribe::<[u64]>()
        .user_header::<BlockHeader>()
        .max_publishers(1)
        .max_subscribers(1)
        .max_nodes(4)
        .history_size(0)
        .subscriber_max_buffer_size(ANSWER_BUFFER)
        .subscriber_max_borrowed_samples(SAMPLES_HELD)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(ice(format!("open block service {name}")))
}

/// Event service a worker listens on for new commands.
pub fn cmd_event_service(
    node: &Node<Svc>,
    worker: usize,
) -> Result<iceoryx2::service::port_factory::event::PortFactory<Svc>, IpcError> {
    let name = format!("w{worker}e");
    let sn =
        ServiceName::new(&name).map_err(|e| IpcError::InvalidName(format!("{name}: {e:?}")))?;
    node.service_builder(&sn)
        .event()
        // The supervisor's notifier, and a waker each worker process whose envs run on
        // threads (`CmdWaker`); a listener each worker process (a replaced one may linger).
        .max_notifiers(5)
        .max_listeners(4)
        .max_nodes(6)
        .event_id_max_value(1)
        .open_or_create()
        .map_err(ice(format!("open command event service {name}")))
}

/// Event service the supervisor listens on for blocks (event id = worker index).
pub fn block_event_service(
    node: &Node<Svc>,
    s: &ChannelSettings,
) -> Result<iceoryx2::service::port_factory::event::PortFactory<Svc>, IpcError> {
    let name = "be";
    let sn = ServiceName::new(name).map_err(|e| IpcError::InvalidName(format!("{name}: {e:?}")))?;
    node.service_builder(&sn)
        .event()
        .max_notifiers(s.max_event_ports())
        .max_listeners(2)
        .max_nodes(s.max_event_ports() + 2)
        .event_id_max_value(s.num_workers.max(1))
        .open_or_create()
        .map_err(ice("open block event service be"))
}
