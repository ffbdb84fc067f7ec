//! Shared-memory transport of one Rogue-Gym environment pool.
//!
//! This crate is the *transport only*: it knows nothing of games, observations or actions. The
//! pool crate (`rogue-gym-pool`) builds its supervisor and worker on top of it.
//!
//! What it provides, for one pool:
//! * **Naming** ([`PoolId`]): one short unique prefix (`rg<8hex>_`) and one short root directory
//!   per pool, so several pools coexist and unix socket paths stay under 108 bytes.
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
//! * **Waiting** ([`WaitPolicy`], [`hybrid_wait`]): yield-poll for a bounded budget, then block
//!   on an iceoryx2 event listener with a timeout. Never an unbounded spin.
//! * **Cleanup** ([`remove_pool_files`], [`sweep_stale_pools`], [`cleanup_dead_nodes`]):
//!   remove a pool's `/dev/shm` files and directories, including iceoryx2's leftover
//!   `*.global_mgmt` counter, and sweep pools whose owner process is dead.
//!
//! All nodes are created with [`SignalHandlingMode::Disabled`]: the pool may be hosted inside a
//! Python interpreter and must not take SIGINT away from it. All ports use
//! [`ipc_threadsafe::Service`], so supervisor-side ports and received samples are `Send`.

#![warn(missing_docs)]

use std::fs;
use std::io::Write;
use std::path::{Path as StdPath, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use iceoryx2::sample_mut::SampleMut;

pub use iceoryx2;

/// The iceoryx2 service flavour used by every port of a pool (thread-safe, so ports are `Send`).
pub type Svc = ipc_threadsafe::Service;

/// A received block of words: an owned handle on a shared-memory sample. It is `Send`; the
/// memory stays mapped and unmodified for as long as the value lives.
pub type BlockSample = Sample<Svc, [u64], BlockHeader>;

/// A loaned, writable block sample (worker side).
pub type BlockSampleMut = SampleMut<Svc, [u64], BlockHeader>;

/// Errors of the transport layer. Every message says which resource failed and why.
#[derive(Debug, thiserror::Error)]
pub enum IpcError {
    /// An iceoryx2 call failed.
    #[error("iceoryx2: {what} failed: {detail}")]
    Iceoryx {
        /// What was attempted (service or port name included).
        what: String,
        /// iceoryx2's error.
        detail: String,
    },
    /// A file-system operation on the pool's files failed.
    #[error("{what} ({path}): {source}")]
    Io {
        /// What was attempted.
        what: &'static str,
        /// The path involved.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A name or path does not fit iceoryx2's limits.
    #[error("invalid pool name or path: {0}")]
    InvalidName(String),
    /// A shared resource does not have the size this side expects.
    #[error("size mismatch: {0}")]
    SizeMismatch(String),
}

fn ice<E: std::fmt::Debug>(what: impl Into<String>) -> impl FnOnce(E) -> IpcError {
    let what = what.into();
    move |e| IpcError::Iceoryx {
        what,
        detail: format!("{e:?}"),
    }
}

// ---------------------------------------------------------------------------------------------
// Naming
// ---------------------------------------------------------------------------------------------

/// Default directory under which each pool gets its short root directory.
pub const DEFAULT_BASE_DIR: &str = "/tmp/rgp";

/// Where a pool's files live. `/dev/shm/<prefix>*` holds its shared memory, `root()` the
/// iceoryx2 root (service and node descriptions, event sockets), `aux_dir()` the pool's own
/// files (owner pid, worker configuration, worker stderr logs).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PoolId {
    name: String,
    base: PathBuf,
}

static POOL_COUNTER: AtomicU64 = AtomicU64::new(0);

fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl PoolId {
    /// A fresh, unique pool identity under `base` (e.g. [`DEFAULT_BASE_DIR`]). The name is
    /// `rg` plus 8 hex digits derived from pid, time and a per-process counter.
    pub fn new_unique(base: &StdPath) -> Result<PoolId, IpcError> {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos() as u64)
            .unwrap_or(0);
        let n = POOL_COUNTER.fetch_add(1, Ordering::Relaxed);
        let h = mix64(nanos ^ mix64(u64::from(std::process::id()) ^ mix64(n)));
        Self::from_parts(&format!("rg{:08x}", h as u32), base)
    }

    /// Rebuild a pool identity from its name (as printed by [`PoolId::name`]) and base dir;
    /// workers use this with the values the supervisor passed them.
    pub fn from_parts(name: &str, base: &StdPath) -> Result<PoolId, IpcError> {
        if name.is_empty()
            || name.len() > 16
            || !name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
        {
            return Err(IpcError::InvalidName(format!(
                "pool name {name:?} must be 1-16 ASCII letters/digits"
            )));
        }
        let id = PoolId {
            name: name.to_string(),
            base: base.to_path_buf(),
        };
        // root + prefix + 30 digits + ".event" must stay below 108 bytes (unix socket limit).
        let sock_len = id.root().as_os_str().len() + 1 + id.prefix().len() + 30 + 6;
        if sock_len >= 108 {
            return Err(IpcError::InvalidName(format!(
                "base directory {} is too long: iceoryx2 socket paths would be {sock_len} bytes \
                 (limit 107); use a shorter base dir such as /tmp/rgp",
                base.display()
            )));
        }
        Ok(id)
    }

    /// The pool's short name, e.g. `rg1a2b3c4d`.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// The base directory that holds this and other pools.
    pub fn base(&self) -> &StdPath {
        &self.base
    }
    /// The iceoryx2 file prefix (`<name>_`): every `/dev/shm` file of the pool starts with it.
    pub fn prefix(&self) -> String {
        format!("{}_", self.name)
    }
    /// iceoryx2's root directory for this pool.
    pub fn root(&self) -> PathBuf {
        self.base.join(&self.name)
    }
    /// The pool's own directory (owner file, worker config, worker logs).
    pub fn aux_dir(&self) -> PathBuf {
        self.base.join(format!("{}.d", self.name))
    }

    /// Create the pool's directories and its owner file (this process). Call once, in the
    /// supervisor, before any node is created.
    pub fn create_dirs(&self) -> Result<(), IpcError> {
        let aux = self.aux_dir();
        fs::create_dir_all(&aux).map_err(|source| IpcError::Io {
            what: "create pool directory",
            path: aux.clone(),
            source,
        })?;
        let owner = aux.join("owner");
        let pid = std::process::id();
        let start = process_start_time(pid).unwrap_or(0);
        let mut f = fs::File::create(&owner).map_err(|source| IpcError::Io {
            what: "write pool owner file",
            path: owner.clone(),
            source,
        })?;
        writeln!(f, "{pid} {start}").map_err(|source| IpcError::Io {
            what: "write pool owner file",
            path: owner.clone(),
            source,
        })?;
        let root = self.root();
        fs::create_dir_all(&root).map_err(|source| IpcError::Io {
            what: "create iceoryx2 root directory",
            path: root,
            source,
        })?;
        Ok(())
    }

    /// The iceoryx2 configuration that confines every resource of the pool to its prefix and
    /// root. Both sides must use it.
    pub fn config(&self) -> Result<Config, IpcError> {
        let mut cfg = Config::default();
        cfg.global.prefix = FileName::new(self.prefix().as_bytes())
            .map_err(|e| IpcError::InvalidName(format!("prefix {}: {e:?}", self.prefix())))?;
        let root = format!("{}/", self.root().display());
        let path = Path::new(root.as_bytes())
            .map_err(|e| IpcError::InvalidName(format!("root {root}: {e:?}")))?;
        cfg.global.set_root_path(&path);
        Ok(cfg)
    }

    /// Create a node of this pool, with signal handling disabled. iceoryx2's log level is set
    /// to errors only unless `IOX2_LOG_LEVEL` says otherwise.
    pub fn node(&self, name: &str) -> Result<Node<Svc>, IpcError> {
        static LOG: std::sync::Once = std::sync::Once::new();
        LOG.call_once(|| set_log_level_from_env_or(LogLevel::Error));
        let cfg = self.config()?;
        let node_name = NodeName::new(name)
            .map_err(|e| IpcError::InvalidName(format!("node {name}: {e:?}")))?;
        NodeBuilder::new()
            .name(&node_name)
            .config(&cfg)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Svc>()
            .map_err(ice(format!("create node {name} of pool {}", self.name)))
    }
}

/// The start time (in clock ticks since boot) of a process, from `/proc/<pid>/stat`; `None` if
/// the process does not exist. Used to tell a live owner from a reused pid.
pub fn process_start_time(pid: u32) -> Option<u64> {
    let s = fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let rest = &s[s.rfind(')')? + 2..];
    // Fields after the command: state is field 3; starttime is field 22 -> index 19 here.
    rest.split_whitespace().nth(19)?.parse().ok()
}

// ---------------------------------------------------------------------------------------------
// Cleanup
// ---------------------------------------------------------------------------------------------

const SHM_DIR: &str = "/dev/shm";

/// The `/dev/shm` files whose name starts with the pool's prefix.
pub fn pool_shm_files(id: &PoolId) -> Vec<PathBuf> {
    let prefix = id.prefix();
    let mut out = Vec::new();
    if let Ok(rd) = fs::read_dir(SHM_DIR) {
        for e in rd.flatten() {
            if e.file_name().to_string_lossy().starts_with(&prefix) {
                out.push(e.path());
            }
        }
    }
    out
}

/// Remove every file of a pool: `/dev/shm/<prefix>*` (including iceoryx2's `*.global_mgmt`
/// counter), the iceoryx2 root and the pool's own directory. Call only once no process of the
/// pool is alive. Missing files are not an error.
pub fn remove_pool_files(id: &PoolId) -> Result<(), IpcError> {
    for p in pool_shm_files(id) {
        match fs::remove_file(&p) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(source) => {
                return Err(IpcError::Io {
                    what: "remove shared-memory file",
                    path: p,
                    source,
                });
            }
        }
    }
    for dir in [id.root(), id.aux_dir()] {
        match fs::remove_dir_all(&dir) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(source) => {
                return Err(IpcError::Io {
                    what: "remove pool directory",
                    path: dir,
                    source,
                });
            }
        }
    }
    Ok(())
}

/// Whether the owner recorded in a pool's owner file is still running.
fn owner_alive(id: &PoolId) -> bool {
    let Ok(s) = fs::read_to_string(id.aux_dir().join("owner")) else {
        return false;
    };
    let mut it = s.split_whitespace();
    let (Some(Ok(pid)), Some(Ok(start))) = (
        it.next().map(str::parse::<u32>),
        it.next().map(str::parse::<u64>),
    ) else {
        return false;
    };
    match process_start_time(pid) {
        Some(t) => start == 0 || t == start,
        None => false,
    }
}

/// A pool whose owner file is not written yet but whose directory is only seconds old is being
/// created by a live process: leave it alone.
fn young_without_owner(id: &PoolId) -> bool {
    if id.aux_dir().join("owner").exists() {
        return false;
    }
    let dir = if id.aux_dir().exists() {
        id.aux_dir()
    } else {
        id.root()
    };
    fs::metadata(dir)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.elapsed().ok())
        .is_some_and(|age| age < Duration::from_secs(10))
}

fn is_pool_name(s: &str) -> bool {
    s.len() == 10 && s.starts_with("rg") && s[2..].bytes().all(|b| b.is_ascii_hexdigit())
}

/// Remove the files of every pool under `base` whose owner process is dead (pools left behind
/// by a killed supervisor). A pool's aux directory (with the owner file) is created before and
/// removed after all its other files, so every leftover is found through it. Returns the names of the pools removed. Safe to run while other live pools exist.
pub fn sweep_stale_pools(base: &StdPath) -> Vec<String> {
    let mut removed = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    if let Ok(rd) = fs::read_dir(base) {
        for e in rd.flatten() {
            let fname = e.file_name().to_string_lossy().into_owned();
            let name = fname.strip_suffix(".d").unwrap_or(&fname).to_string();
            if !is_pool_name(&name) || !seen.insert(name.clone()) {
                continue;
            }
            if let Ok(id) = PoolId::from_parts(&name, base) {
                // A pool creates its aux dir (with the owner file) before anything else.
                if young_without_owner(&id) {
                    continue; // being created right now
                }
                if !owner_alive(&id) && remove_pool_files(&id).is_ok() {
                    removed.push(name);
                }
            }
        }
    }
    removed
}

/// Remove the iceoryx2 resources of this pool's dead nodes (e.g. a killed worker). Returns the
/// number of nodes cleaned.
pub fn cleanup_dead_nodes(id: &PoolId) -> Result<usize, IpcError> {
    let cfg = id.config()?;
    let mut n = 0;
    Node::<Svc>::list(&cfg, |state| {
        if let NodeState::Dead(d) = state
            && d.try_remove_stale_resources().is_ok()
        {
            n += 1;
        }
        CallbackProgression::Continue
    })
    .map_err(ice("list nodes"))?;
    Ok(n)
}

// ---------------------------------------------------------------------------------------------
// Headers and service settings
// ---------------------------------------------------------------------------------------------

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
}

/// Settings that both sides of a pool must agree on (pass them to the worker unchanged).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChannelSettings {
    /// Number of workers of the pool (event ids `0..num_workers`).
    pub num_workers: usize,
    /// Samples of one worker the supervisor side may hold at once (e.g. zero-copy numpy views
    /// kept alive by a trainer). Receiving more fails with a "borrow" error.
    pub max_borrowed: usize,
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
        .subscriber_max_buffer_size(2)
        .subscriber_max_borrowed_samples(1)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(ice(format!("open command service {name}")))
}

/// Publish-subscribe service of a worker's blocks (observations and per-env records).
pub fn block_service(
    node: &Node<Svc>,
    worker: usize,
    s: &ChannelSettings,
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
        .subscriber_max_buffer_size(4)
        .subscriber_max_borrowed_samples(s.max_borrowed.max(1))
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
        .max_notifiers(4)
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

// ---------------------------------------------------------------------------------------------
// Ports
// ---------------------------------------------------------------------------------------------

/// Supervisor-side ports of one worker. `Send`.
pub struct SupervisorPorts {
    cmd_pub: Publisher<Svc, [u64], CmdHeader>,
    cmd_notifier: Notifier<Svc>,
    block_sub: Subscriber<Svc, [u64], BlockHeader>,
}

impl std::fmt::Debug for SupervisorPorts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SupervisorPorts")
    }
}

impl SupervisorPorts {
    /// Open the ports of worker `worker`; `max_cmd_words` is the largest command payload.
    pub fn new(
        node: &Node<Svc>,
        worker: usize,
        max_cmd_words: usize,
        s: &ChannelSettings,
    ) -> Result<Self, IpcError> {
        let block_sub = block_service(node, worker, s)?
            .subscriber_builder()
            .create()
            .map_err(ice(format!("create block subscriber of worker {worker}")))?;
        let cmd_pub = cmd_service(node, worker)?
            .publisher_builder()
            .initial_max_slice_len(max_cmd_words.max(1))
            .max_loaned_samples(1)
            .create()
            .map_err(ice(format!("create command publisher of worker {worker}")))?;
        let cmd_notifier = cmd_event_service(node, worker)?
            .notifier_builder()
            .create()
            .map_err(ice(format!("create command notifier of worker {worker}")))?;
        Ok(SupervisorPorts {
            cmd_pub,
            cmd_notifier,
            block_sub,
        })
    }

    /// Send a command: `fill` writes the payload words (all `len` of them), then the worker is
    /// woken up.
    pub fn send_cmd(
        &self,
        seq: u64,
        kind: u32,
        len: usize,
        fill: impl FnOnce(&mut [u64]),
    ) -> Result<(), IpcError> {
        let s = self
            .cmd_pub
            .loan_slice(len.max(1))
            .map_err(ice("loan command sample"))?;
        let mut s = s;
        *s.user_header_mut() = CmdHeader {
            seq,
            kind,
            len: len as u32,
        };
        fill(&mut s.payload_mut()[..len]);
        s.send().map_err(ice("send command"))?;
        self.cmd_notifier.notify().map_err(ice("notify worker"))?;
        Ok(())
    }

    /// Take the next received block, if any.
    pub fn try_recv(&self) -> Result<Option<BlockSample>, IpcError> {
        self.block_sub.receive().map_err(ice("receive block"))
    }
}

/// The supervisor's listener for "a block is ready" events.
pub struct BlockListener {
    listener: Listener<Svc>,
}

impl std::fmt::Debug for BlockListener {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("BlockListener")
    }
}

impl BlockListener {
    /// Create the listener (supervisor side).
    pub fn new(node: &Node<Svc>, s: &ChannelSettings) -> Result<Self, IpcError> {
        let listener = block_event_service(node, s)?
            .listener_builder()
            .create()
            .map_err(ice("create block listener"))?;
        Ok(BlockListener { listener })
    }
    /// The underlying listener (for [`hybrid_wait`]).
    pub fn listener(&self) -> &Listener<Svc> {
        &self.listener
    }
}

/// Worker-side ports.
pub struct WorkerPorts {
    cmd_sub: Subscriber<Svc, [u64], CmdHeader>,
    cmd_listener: Listener<Svc>,
    block_pub: Publisher<Svc, [u64], BlockHeader>,
    block_notifier: Notifier<Svc>,
}

impl std::fmt::Debug for WorkerPorts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("WorkerPorts")
    }
}

impl WorkerPorts {
    /// Open the ports of worker `worker`; `block_words` is the payload size of every block.
    pub fn new(
        node: &Node<Svc>,
        worker: usize,
        block_words: usize,
        s: &ChannelSettings,
    ) -> Result<Self, IpcError> {
        let cmd_sub = cmd_service(node, worker)?
            .subscriber_builder()
            .create()
            .map_err(ice(format!("create command subscriber of worker {worker}")))?;
        let cmd_listener = cmd_event_service(node, worker)?
            .listener_builder()
            .create()
            .map_err(ice(format!("create command listener of worker {worker}")))?;
        let block_pub = block_service(node, worker, s)?
            .publisher_builder()
            .initial_max_slice_len(block_words.max(1))
            .max_loaned_samples(1)
            .create()
            .map_err(ice(format!("create block publisher of worker {worker}")))?;
        let event_id = EventId::new(worker);
        let block_notifier = block_event_service(node, s)?
            .notifier_builder()
            .default_event_id(event_id)
            .create()
            .map_err(ice(format!("create block notifier of worker {worker}")))?;
        Ok(WorkerPorts {
            cmd_sub,
            cmd_listener,
            block_pub,
            block_notifier,
        })
    }

    /// Take the next command, if any.
    pub fn try_recv_cmd(&self) -> Result<Option<Sample<Svc, [u64], CmdHeader>>, IpcError> {
        self.cmd_sub.receive().map_err(ice("receive command"))
    }

    /// The listener woken by new commands (for [`hybrid_wait`]).
    pub fn cmd_listener(&self) -> &Listener<Svc> {
        &self.cmd_listener
    }

    /// Loan a block of `words` payload words. The memory is the publisher's shared-memory chunk
    /// (initialised memory: zero-filled by the kernel, or a previous block's content).
    pub fn loan_block(&self, words: usize) -> Result<BlockSampleMut, IpcError> {
        let s = self
            .block_pub
            .loan_slice_uninit(words.max(1))
            .map_err(ice("loan block sample"))?;
        // SAFETY: the chunk lives in a shared-memory mapping which the kernel zero-fills and
        // which only ever holds plain integer data written by previous blocks: every bit
        // pattern is a valid u64, so the memory is initialised.
        Ok(unsafe { s.assume_init() })
    }

    /// Publish a block and wake the supervisor.
    pub fn send_block(&self, s: BlockSampleMut) -> Result<(), IpcError> {
        s.send().map_err(ice("send block"))?;
        self.block_notifier
            .notify()
            .map_err(ice("notify supervisor"))?;
        Ok(())
    }
}

/// View a block's words as bytes.
pub fn words_as_bytes(w: &[u64]) -> &[u8] {
    // SAFETY: u8 has alignment 1 and every byte of a u64 is initialised.
    unsafe { std::slice::from_raw_parts(w.as_ptr().cast::<u8>(), std::mem::size_of_val(w)) }
}

/// View a block's words as mutable bytes.
pub fn words_as_bytes_mut(w: &mut [u64]) -> &mut [u8] {
    // SAFETY: as above; any byte pattern is a valid u64.
    unsafe { std::slice::from_raw_parts_mut(w.as_mut_ptr().cast::<u8>(), std::mem::size_of_val(w)) }
}

// ---------------------------------------------------------------------------------------------
// Shared batch buffer
// ---------------------------------------------------------------------------------------------

/// A plain shared-memory buffer of a pool (`/dev/shm/<prefix><name>`, so pool cleanup removes
/// it), mapped read-write in every process that opens it. Used for batch observation slots that
/// workers write directly. It has no synchronisation of its own: the pool's command/answer
/// protocol decides who may touch which bytes when.
pub struct SharedBuffer {
    ptr: std::ptr::NonNull<std::ffi::c_void>,
    len: usize,
    path: PathBuf,
}

// SAFETY: the mapping is plain memory owned by this value; access discipline is the caller's.
unsafe impl Send for SharedBuffer {}
// SAFETY: shared references only hand out raw pointers / reads synchronised by the protocol.
unsafe impl Sync for SharedBuffer {}

impl std::fmt::Debug for SharedBuffer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SharedBuffer")
            .field("path", &self.path)
            .field("len", &self.len)
            .finish()
    }
}

impl SharedBuffer {
    fn path_of(id: &PoolId, name: &str) -> PathBuf {
        StdPath::new(SHM_DIR).join(format!("{}{name}", id.prefix()))
    }

    /// Create (or truncate) the buffer `name` of `len` bytes (zero-filled) and map it.
    pub fn create(id: &PoolId, name: &str, len: usize) -> Result<Self, IpcError> {
        let path = Self::path_of(id, name);
        let f = fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)
            .map_err(|source| IpcError::Io {
                what: "create shared buffer",
                path: path.clone(),
                source,
            })?;
        f.set_len(len as u64).map_err(|source| IpcError::Io {
            what: "size shared buffer",
            path: path.clone(),
            source,
        })?;
        Self::map(f, path, len)
    }

    /// Open and map an existing buffer `name` of `len` bytes.
    pub fn open(id: &PoolId, name: &str, len: usize) -> Result<Self, IpcError> {
        let path = Self::path_of(id, name);
        let f = fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&path)
            .map_err(|source| IpcError::Io {
                what: "open shared buffer",
                path: path.clone(),
                source,
            })?;
        let actual = f.metadata().map(|m| m.len()).unwrap_or(0);
        if actual < len as u64 {
            return Err(IpcError::SizeMismatch(format!(
                "shared buffer {} has {actual} bytes, expected {len}: supervisor and worker \
                 disagree (different builds?)",
                path.display()
            )));
        }
        Self::map(f, path, len)
    }

    fn map(f: fs::File, path: PathBuf, len: usize) -> Result<Self, IpcError> {
        use nix::sys::mman::{MapFlags, ProtFlags, mmap};
        let n = std::num::NonZeroUsize::new(len.max(1)).unwrap_or(std::num::NonZeroUsize::MIN);
        // SAFETY: a fresh shared mapping of a file we opened; no existing memory is affected.
        let ptr = unsafe {
            mmap(
                None,
                n,
                ProtFlags::PROT_READ | ProtFlags::PROT_WRITE,
                MapFlags::MAP_SHARED,
                &f,
                0,
            )
        }
        .map_err(|e| IpcError::Io {
            what: "map shared buffer",
            path: path.clone(),
            source: std::io::Error::from(e),
        })?;
        Ok(SharedBuffer {
            ptr,
            len: len.max(1),
            path,
        })
    }

    /// Start of the mapping (page aligned).
    pub fn as_ptr(&self) -> *mut u8 {
        self.ptr.as_ptr().cast()
    }
    /// Length in bytes.
    pub fn len(&self) -> usize {
        self.len
    }
    /// Whether the buffer is empty (never: at least one byte is mapped).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl Drop for SharedBuffer {
    fn drop(&mut self) {
        // SAFETY: we own the mapping; nobody uses it after drop (borrowers hold `&self`).
        let _ = unsafe { nix::sys::mman::munmap(self.ptr, self.len) };
    }
}

// ---------------------------------------------------------------------------------------------
// Waiting
// ---------------------------------------------------------------------------------------------

/// How a side waits for the other: yield-poll for `poll_budget`, then block on the event
/// listener in slices of `block_slice` (between slices the caller's idle hook runs: liveness
/// checks, timeouts).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaitPolicy {
    /// How long to poll with `yield_now` before blocking. Keep it at tens of µs.
    pub poll_budget: Duration,
    /// Longest single blocking wait on the listener.
    pub block_slice: Duration,
    /// Poll with `sched_yield` between checks (`true`), or spin with a CPU pause hint
    /// (`false`; never gives the CPU away, but is still bounded by `poll_budget`).
    pub yield_cpu: bool,
}

impl Default for WaitPolicy {
    fn default() -> Self {
        WaitPolicy {
            poll_budget: Duration::from_micros(50),
            block_slice: Duration::from_millis(10),
            yield_cpu: true,
        }
    }
}

/// Outcome of [`hybrid_wait`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaitOutcome {
    /// The callback reported completion.
    Done,
    /// The deadline passed first.
    TimedOut,
}

/// Why [`hybrid_wait`] calls its callback.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaitCall {
    /// Check for new data; return `true` when the wait is over.
    Poll,
    /// A blocking slice passed (with or without events): run liveness checks and timeouts, then
    /// poll; return `true` when the wait is over.
    Idle,
}

/// Wait until `f(WaitCall::Poll)` returns `true`: poll with `yield_now` for the policy's
/// budget, then block on `listener` (in slices of `block_slice`) and poll again after each
/// wake-up. At least once per `block_slice` of blocking, `f(WaitCall::Idle)` runs instead (use
/// it for liveness checks and timeouts); a signal interrupting the blocking wait (EINTR) is
/// not an error but also leads to an `Idle` call. An error from `f` ends the wait. `deadline` bounds the
/// whole wait. Never spins unboundedly: idle waiting uses no CPU.
pub fn hybrid_wait<E: From<IpcError>>(
    listener: &Listener<Svc>,
    policy: &WaitPolicy,
    deadline: Option<Instant>,
    mut f: impl FnMut(WaitCall) -> Result<bool, E>,
) -> Result<WaitOutcome, E> {
    if f(WaitCall::Poll)? {
        return Ok(WaitOutcome::Done);
    }
    let start = Instant::now();
    while start.elapsed() < policy.poll_budget {
        if policy.yield_cpu {
            std::thread::yield_now();
        } else {
            for _ in 0..64 {
                std::hint::spin_loop();
            }
        }
        if f(WaitCall::Poll)? {
            return Ok(WaitOutcome::Done);
        }
    }
    let mut last_idle = Instant::now();
    loop {
        let mut slice = policy.block_slice;
        if let Some(d) = deadline {
            let now = Instant::now();
            if now >= d {
                return Ok(WaitOutcome::TimedOut);
            }
            slice = slice.min(d - now);
        }
        // A signal (e.g. SIGINT) interrupting the blocking wait is a wake-up, not an error:
        // the Idle call below lets the caller react to it (run its signal check).
        let (n, interrupted) = match listener.timed_wait(|_| {}, slice) {
            Ok(n) => (n, false),
            Err(iceoryx2::port::listener::ListenerWaitError::InterruptSignal) => (0, true),
            Err(e) => return Err(ice("wait on event listener")(e).into()),
        };
        let call = if n == 0 || interrupted || last_idle.elapsed() >= policy.block_slice {
            last_idle = Instant::now();
            WaitCall::Idle
        } else {
            WaitCall::Poll
        };
        if f(call)? {
            return Ok(WaitOutcome::Done);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_short_and_unique() {
        let a = PoolId::new_unique(StdPath::new(DEFAULT_BASE_DIR)).unwrap();
        let b = PoolId::new_unique(StdPath::new(DEFAULT_BASE_DIR)).unwrap();
        assert_ne!(a.name(), b.name());
        assert!(is_pool_name(a.name()));
        assert_eq!(a.prefix().len(), 11);
        assert!(PoolId::from_parts("x", &StdPath::new("/tmp").join("a".repeat(90))).is_err());
        assert!(PoolId::from_parts("bad/name", StdPath::new("/tmp")).is_err());
    }

    #[test]
    fn own_process_is_alive_and_start_time_readable() {
        assert!(process_start_time(std::process::id()).is_some());
        assert!(process_start_time(u32::MAX - 1).is_none());
    }

    #[test]
    fn pubsub_round_trip_and_cleanup() {
        let base = std::env::temp_dir().join("rgp-ipc-test");
        let id = PoolId::new_unique(&base).unwrap();
        id.create_dirs().unwrap();
        let s = ChannelSettings {
            num_workers: 1,
            max_borrowed: 2,
        };
        {
            let sup_node = id.node("sup").unwrap();
            let sup = SupervisorPorts::new(&sup_node, 0, 4, &s).unwrap();
            let bl = BlockListener::new(&sup_node, &s).unwrap();
            let w_node = id.node("w0").unwrap();
            let w = WorkerPorts::new(&w_node, 0, 8, &s).unwrap();
            sup.send_cmd(1, 7, 3, |p| p.copy_from_slice(&[1, 2, 3]))
                .unwrap();
            let mut got = None;
            hybrid_wait::<IpcError>(
                w.cmd_listener(),
                &WaitPolicy::default(),
                Some(Instant::now() + Duration::from_secs(5)),
                |_| {
                    got = w.try_recv_cmd()?;
                    Ok(got.is_some())
                },
            )
            .unwrap();
            let c = got.unwrap();
            assert_eq!(c.user_header().kind, 7);
            assert_eq!(&c.payload()[..3], &[1, 2, 3]);
            let mut b = w.loan_block(8).unwrap();
            b.payload_mut().fill(9);
            *b.user_header_mut() = BlockHeader {
                seq: 1,
                generation: 0,
                worker: 0,
                kind: 2,
            };
            w.send_block(b).unwrap();
            let mut blk = None;
            let out = hybrid_wait::<IpcError>(
                bl.listener(),
                &WaitPolicy::default(),
                Some(Instant::now() + Duration::from_secs(5)),
                |_| {
                    blk = sup.try_recv()?;
                    Ok(blk.is_some())
                },
            )
            .unwrap();
            assert_eq!(out, WaitOutcome::Done);
            let blk = blk.unwrap();
            assert_eq!(blk.payload(), &[9u64; 8]);
            assert_eq!(words_as_bytes(blk.payload()).len(), 64);
        }
        assert!(!pool_shm_files(&id).is_empty());
        remove_pool_files(&id).unwrap();
        assert!(pool_shm_files(&id).is_empty());
        assert!(!id.root().exists() && !id.aux_dir().exists());
        let _ = fs::remove_dir(&base);
    }

    /// CPU time (utime + stime, clock ticks) of the calling thread.
    fn thread_cpu_ticks() -> u64 {
        let s = fs::read_to_string("/proc/thread-self/stat").unwrap();
        let rest = &s[s.rfind(')').unwrap() + 2..];
        let f: Vec<&str> = rest.split_whitespace().collect();
        f[11].parse::<u64>().unwrap() + f[12].parse::<u64>().unwrap()
    }

    #[test]
    fn idle_wait_blocks_instead_of_spinning() {
        let base = std::env::temp_dir().join("rgp-ipc-idle-test");
        let id = PoolId::new_unique(&base).unwrap();
        id.create_dirs().unwrap();
        let s = ChannelSettings {
            num_workers: 1,
            max_borrowed: 2,
        };
        {
            let node = id.node("sup").unwrap();
            let bl = BlockListener::new(&node, &s).unwrap();
            let before = thread_cpu_ticks();
            let t0 = Instant::now();
            let mut idles = 0;
            let out = hybrid_wait::<IpcError>(
                bl.listener(),
                &WaitPolicy::default(),
                Some(Instant::now() + Duration::from_millis(400)),
                |c| {
                    if c == WaitCall::Idle {
                        idles += 1;
                    }
                    Ok(false)
                },
            )
            .unwrap();
            assert_eq!(out, WaitOutcome::TimedOut);
            assert!(t0.elapsed() >= Duration::from_millis(400));
            assert!(idles >= 10, "idle hook runs every block slice ({idles})");
            // 400 ms of waiting cost (much) less than 100 ms of CPU (ticks are 10 ms).
            assert!(thread_cpu_ticks() - before < 10);
        }
        remove_pool_files(&id).unwrap();
        let _ = fs::remove_dir(&base);
    }

    #[test]
    fn sweep_removes_pools_of_dead_owners_only() {
        let base = std::env::temp_dir().join("rgp-ipc-sweep-test");
        let live = PoolId::new_unique(&base).unwrap();
        live.create_dirs().unwrap();
        let dead = PoolId::new_unique(&base).unwrap();
        dead.create_dirs().unwrap();
        // Fake a dead owner.
        fs::write(dead.aux_dir().join("owner"), "4294967294 1\n").unwrap();
        let removed = sweep_stale_pools(&base);
        assert!(removed.contains(&dead.name().to_string()));
        assert!(!dead.aux_dir().exists());
        assert!(live.aux_dir().exists());
        remove_pool_files(&live).unwrap();
        let _ = fs::remove_dir(&base);
    }
}
