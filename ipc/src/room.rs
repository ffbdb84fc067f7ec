//! Room in the shared-memory filesystem (`/dev/shm`): how large it is, how much is free, and
//! the error that says a pool does not fit, with the fixes.
//!
//! What a pool keeps there is iceoryx2's: each worker's channels (its command and answer
//! blocks). A tmpfs lets a file be sized beyond its free space; the pages are taken only when
//! written, and a process that writes a page the filesystem cannot give is killed by SIGBUS.
//! So a pool checks its need against the free space before it creates anything
//! ([`check_room`]). The pool's own buffers are not there ([`crate::SharedBuffer`]: memory
//! files whose pages are reserved when they are made).

use crate::error::IpcError;
use crate::naming::SHM_DIR;

/// The size and free space of the shared-memory filesystem, in bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShmRoom {
    /// Total size.
    pub size: u64,
    /// Free space, for this (unprivileged) user.
    pub free: u64,
}

/// The size and free space of `/dev/shm`.
pub fn shm_room() -> Result<ShmRoom, IpcError> {
    let st = nix::sys::statvfs::statvfs(SHM_DIR).map_err(|e| IpcError::Io {
        what: "measure the shared-memory filesystem",
        path: SHM_DIR.into(),
        source: std::io::Error::from(e),
    })?;
    let frag = st.fragment_size() as u64;
    Ok(ShmRoom {
        size: st.blocks() as u64 * frag,
        free: st.blocks_available() as u64 * frag,
    })
}

/// `Ok` when `/dev/shm` has `need` bytes free, else [`IpcError::NoRoom`] with its numbers.
pub fn check_room(need: u64) -> Result<(), IpcError> {
    let room = shm_room()?;
    if room.free >= need {
        Ok(())
    } else {
        Err(no_room(need, room))
    }
}

/// The error of a pool that needs `need` bytes where `room` is what there is.
pub fn no_room(need: u64, room: ShmRoom) -> IpcError {
    IpcError::NoRoom {
        dir: SHM_DIR.into(),
        need,
        size: room.size,
        free: room.free,
    }
}
