//! The shared batch buffer: a plain `/dev/shm` mapping that workers write observations into.

use std::fs;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path as StdPath, PathBuf};

use crate::error::IpcError;
use crate::naming::PoolId;
use crate::naming::SHM_DIR;
use crate::private::{check_private, create_private_file};

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

    /// Create the buffer `name` of `len` bytes (zero-filled, mode 0600, exclusively and without
    /// following a link: a name someone planted is an error), reserve its pages (no room is
    /// [`IpcError::NoRoom`], never a SIGBUS later) and map it.
    pub fn create(id: &PoolId, name: &str, len: usize) -> Result<Self, IpcError> {
        let path = Self::path_of(id, name);
        let f = create_private_file(&path)?;
        f.set_len(len as u64).map_err(|source| IpcError::Io {
            what: "size shared buffer",
            path: path.clone(),
            source,
        })?;
        // Take every page now: on a full tmpfs a write to a page never taken is a SIGBUS.
        if len > 0
            && let Err(e) = nix::fcntl::posix_fallocate(&f, 0, len as nix::libc::off_t)
        {
            drop(f);
            let _ = fs::remove_file(&path);
            return Err(match (e, crate::room::shm_room()) {
                (nix::errno::Errno::ENOSPC, Ok(room)) => crate::room::no_room(len as u64, room),
                _ => IpcError::Io {
                    what: "reserve the pages of the shared buffer",
                    path,
                    source: std::io::Error::from(e),
                },
            });
        }
        Self::map(f, path, len)
    }

    /// Open and map an existing buffer `name` of `len` bytes. It must be a regular file of this
    /// user closed to group and others, reached without a link.
    pub fn open(id: &PoolId, name: &str, len: usize) -> Result<Self, IpcError> {
        let path = Self::path_of(id, name);
        let f = fs::OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(nix::libc::O_NOFOLLOW | nix::libc::O_CLOEXEC)
            .open(&path)
            .map_err(|source| IpcError::Io {
                what: "open shared buffer",
                path: path.clone(),
                source,
            })?;
        let meta = f.metadata().map_err(|source| IpcError::Io {
            what: "inspect shared buffer",
            path: path.clone(),
            source,
        })?;
        check_private(&path, &meta, false)?;
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
