//! Naming: one short unique prefix and one short root directory per pool ([`PoolId`]).

use std::io::Write;
use std::path::{Path as StdPath, PathBuf};

use iceoryx2::prelude::*;

use crate::Svc;
use crate::error::IpcError;
use crate::error::ice;
use crate::private::{create_private_dir, create_private_file, random_u64};

/// Hex digits of the random part of a pool name (`rg` + these): 48 bits nobody can guess, so
/// no one can plant a pool's names before it makes them.
pub const NAME_HEX_DIGITS: usize = 12;

/// Where a pool's files live. `/dev/shm/<prefix>*` holds its shared memory, `root()` the
/// iceoryx2 root (service and node descriptions, event sockets), `aux_dir()` the pool's own
/// files (owner pid, worker configuration, worker stderr logs). Both directories sit in the
/// pool's runtime directory ([`crate::resolve_runtime_dir`]), which only its user can enter.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PoolId {
    name: String,
    base: PathBuf,
}

impl PoolId {
    /// A fresh pool identity in the runtime directory `base`. The name is `rg` plus
    /// [`NAME_HEX_DIGITS`] random hex digits from the kernel's random source.
    pub fn new_unique(base: &StdPath) -> Result<PoolId, IpcError> {
        let r = random_u64()? & ((1u64 << (4 * NAME_HEX_DIGITS)) - 1);
        Self::from_parts(&format!("rg{r:0w$x}", w = NAME_HEX_DIGITS), base)
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
                "runtime directory {} is too long: iceoryx2 socket paths would be {sock_len} bytes \
                 (limit 107); use a shorter runtime directory",
                base.display()
            )));
        }
        Ok(id)
    }

    /// The pool's short name, e.g. `rg1a2b3c4d`.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// The runtime directory that holds this and the user's other pools.
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

    /// Create the pool's directories (0700) and its owner file (0600), each exclusively: an
    /// existing name is an error. Call once, in the supervisor, after the runtime directory was
    /// verified; then create the pool's first `/dev/shm` files and
    /// [`crate::create_node_counter`] before any node.
    pub fn create_dirs(&self) -> Result<(), IpcError> {
        create_private_dir(&self.aux_dir())?;
        let owner = self.aux_dir().join("owner");
        let pid = std::process::id();
        let start = process_start_time(pid).unwrap_or(0);
        let mut f = create_private_file(&owner)?;
        writeln!(f, "{pid} {start}").map_err(|source| IpcError::Io {
            what: "write pool owner file",
            path: owner.clone(),
            source,
        })?;
        create_private_dir(&self.root())
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

pub(crate) const SHM_DIR: &str = "/dev/shm";

/// The `/dev/shm` files whose name starts with the pool's prefix (whoever owns them: a file
/// someone else planted under the pool's prefix is found too).
pub fn pool_shm_files(id: &PoolId) -> Vec<PathBuf> {
    let prefix = id.prefix();
    let mut out = Vec::new();
    if let Ok(rd) = std::fs::read_dir(SHM_DIR) {
        for e in rd.flatten() {
            if e.file_name().to_string_lossy().starts_with(&prefix) {
                out.push(e.path());
            }
        }
    }
    out
}

/// The start time (in clock ticks since boot) of a process, from `/proc/<pid>/stat`; `None` if
/// the process does not exist. Used to tell a live owner from a reused pid.
pub fn process_start_time(pid: u32) -> Option<u64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let rest = &s[s.rfind(')')? + 2..];
    // Fields after the command: state is field 3; starttime is field 22 -> index 19 here.
    rest.split_whitespace().nth(19)?.parse().ok()
}
