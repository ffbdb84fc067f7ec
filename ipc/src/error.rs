//! The transport's error type.

use std::path::PathBuf;

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
    /// A path is not private to this user: planted by someone else, a link, or open to group
    /// or others. The pool refuses it rather than use it.
    #[error(
        "{path} {reason}: refusing it, since another local user could read or replace the pool's files; \
         use a directory only you can enter (set ROGUE_GYM_RUNTIME_DIR, or runtime_dir in the pool settings), see docs/security.md"
    )]
    Insecure {
        /// The path refused.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// The shared-memory filesystem has less free space than the pool needs (Docker, GitHub
    /// Actions containers and Kubernetes pods give `/dev/shm` 64 MiB by default).
    #[error(
        "{dir} has {} free ({} in all), but this pool needs {}: give the container more shared memory \
         (docker run --shm-size=1g, or --ipc=host; in Kubernetes an emptyDir with medium: Memory \
         mounted at /dev/shm), or use fewer envs or less info room (the need there is each \
         worker's channels: its records, final observations and infos, two blocks of them); \
         python -m rogue_gym.doctor checks a machine",
        mib(*free), mib(*size), mib(*need)
    )]
    NoRoom {
        /// The filesystem's mount point.
        dir: PathBuf,
        /// Bytes the pool needs there.
        need: u64,
        /// Its total size.
        size: u64,
        /// Its free space.
        free: u64,
    },
    /// The machine, or the process's memory limit (a container's cgroup), cannot give a
    /// shared buffer its pages.
    #[error(
        "cannot reserve {} for the pool's {what} buffer: the machine or this process's memory \
         limit (a container's cgroup) has no room for it; use fewer envs, smaller observations \
         or fewer batch_slots (2 by default), or give the container more memory; \
         python -m rogue_gym.doctor checks a machine",
        mib(*need)
    )]
    NoMemory {
        /// The buffer (`batch`, `books`, `stats`).
        what: String,
        /// Bytes it needs.
        need: u64,
    },
    /// A shared resource does not have the size this side expects.
    #[error("size mismatch: {0}")]
    SizeMismatch(String),
}

pub(crate) fn ice<E: std::fmt::Debug>(what: impl Into<String>) -> impl FnOnce(E) -> IpcError {
    let what = what.into();
    move |e| IpcError::Iceoryx {
        what,
        detail: format!("{e:?}"),
    }
}

/// `n` bytes as MiB with one decimal, for messages.
pub fn mib(n: u64) -> String {
    format!("{:.1} MiB", n as f64 / (1024.0 * 1024.0))
}
