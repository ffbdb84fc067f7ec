//! Naming: one short unique prefix and one short root directory per pool ([`PoolId`]).

use std::fs;
use std::io::Write;
use std::path::{Path as StdPath, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use iceoryx2::prelude::*;

use crate::Svc;
use crate::error::IpcError;
use crate::error::ice;

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
