//! A pool's shared buffers (the batch slots, the episode books, the counters): anonymous
//! memory files (`memfd_create`) sealed against shrinking and growing, mapped read-write by the
//! supervisor and by every worker it hands the descriptor to.
//!
//! Why not files in `/dev/shm`: a file there can be opened by path and truncated by any
//! process of the user (a worker's env, another pool's), and the supervisor then dies of
//! SIGBUS at its next read of the mapping. A sealed memfd has no path and cannot change size,
//! whoever holds it; its pages go when the last process holding it exits, so a pool that dies
//! leaves nothing behind. It takes memory like any of the process's (a container's memory
//! limit, not `/dev/shm`'s size, bounds it).

use std::os::fd::{AsRawFd, OwnedFd, RawFd};
use std::sync::Mutex;

use nix::fcntl::{FcntlArg, FdFlag, SealFlag, fcntl};
use nix::sys::memfd::{MFdFlags, memfd_create};

use crate::error::IpcError;

/// The seals every buffer carries: it can neither shrink nor grow, and no one can remove that.
fn seals() -> SealFlag {
    SealFlag::F_SEAL_SHRINK | SealFlag::F_SEAL_GROW | SealFlag::F_SEAL_SEAL
}

/// A shared buffer of a pool, mapped read-write in every process that holds it. It has no
/// synchronisation of its own: the pool's command/answer protocol decides who may touch which
/// bytes when.
pub struct SharedBuffer {
    ptr: std::ptr::NonNull<std::ffi::c_void>,
    len: usize,
    name: String,
    /// The memory file, kept by its creator to hand to the workers it spawns, until
    /// [`SharedBuffer::close_fd`] (the mapping lives on while views of it do).
    fd: Mutex<Option<OwnedFd>>,
}

// SAFETY: the mapping is plain memory owned by this value; access discipline is the caller's.
unsafe impl Send for SharedBuffer {}
// SAFETY: shared references only hand out raw pointers / reads synchronised by the protocol.
unsafe impl Sync for SharedBuffer {}

impl std::fmt::Debug for SharedBuffer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SharedBuffer")
            .field("name", &self.name)
            .field("len", &self.len)
            .finish()
    }
}

fn io(what: &'static str, name: &str, e: nix::errno::Errno) -> IpcError {
    IpcError::Io {
        what,
        path: format!("memfd:{name}").into(),
        source: std::io::Error::from(e),
    }
}

impl SharedBuffer {
    /// Create buffer `name` (a label for error messages and `/proc/<pid>/fd`) of `len` bytes,
    /// zero-filled: a memory file of this process alone, its pages reserved now (no memory is
    /// [`IpcError::NoMemory`], never a SIGBUS later), sealed against any change of size, and
    /// mapped. Hand it to a worker with `SharedBuffer::fd` (inherited across `exec`) and
    /// [`SharedBuffer::from_fd`].
    pub fn create(name: &str, len: usize) -> Result<Self, IpcError> {
        let flags = MFdFlags::MFD_CLOEXEC | MFdFlags::MFD_ALLOW_SEALING;
        let fd = memfd_create(format!("rogue-gym-{name}").as_str(), flags)
            .map_err(|e| io("create a memory file", name, e))?;
        nix::unistd::ftruncate(&fd, len as nix::libc::off_t)
            .map_err(|e| io("size a memory file", name, e))?;
        // Take every page now: a page the kernel cannot give later is a SIGBUS.
        if len > 0
            && let Err(e) = nix::fcntl::posix_fallocate(&fd, 0, len as nix::libc::off_t)
        {
            return Err(match e {
                nix::errno::Errno::ENOSPC | nix::errno::Errno::ENOMEM => IpcError::NoMemory {
                    what: name.to_string(),
                    need: len as u64,
                },
                e => io("reserve the pages of a memory file", name, e),
            });
        }
        fcntl(&fd, FcntlArg::F_ADD_SEALS(seals()))
            .map_err(|e| io("seal a memory file", name, e))?;
        let buf = Self::map(&fd, name, len)?;
        *buf.fd.lock().unwrap_or_else(|p| p.into_inner()) = Some(fd);
        Ok(buf)
    }

    /// Map buffer `name` of `len` bytes from `fd`, a descriptor its creator handed over
    /// ([`SharedBuffer::create`]): it must be a memory file sealed against shrinking and
    /// growing, of `len` bytes or more. The descriptor is closed once mapped.
    pub fn from_fd(fd: OwnedFd, name: &str, len: usize) -> Result<Self, IpcError> {
        let got = fcntl(&fd, FcntlArg::F_GET_SEALS)
            .map_err(|e| io("read the seals of a memory file", name, e))?;
        let got = SealFlag::from_bits_truncate(got);
        if !got.contains(SealFlag::F_SEAL_SHRINK | SealFlag::F_SEAL_GROW) {
            return Err(IpcError::SizeMismatch(format!(
                "the {name} descriptor is not a sealed memory file (seals {got:?}): run workers \
                 through the pool that spawns them"
            )));
        }
        let actual = nix::sys::stat::fstat(&fd)
            .map_err(|e| io("inspect a memory file", name, e))?
            .st_size;
        if (actual as u64) < len as u64 {
            return Err(IpcError::SizeMismatch(format!(
                "the {name} buffer has {actual} bytes, expected {len}: supervisor and worker \
                 disagree (different builds?)"
            )));
        }
        Self::map(&fd, name, len)
    }

    fn map(fd: &OwnedFd, name: &str, len: usize) -> Result<Self, IpcError> {
        use nix::sys::mman::{MapFlags, ProtFlags, mmap};
        let n = std::num::NonZeroUsize::new(len.max(1)).unwrap_or(std::num::NonZeroUsize::MIN);
        // SAFETY: a fresh shared mapping of a file we hold; no existing memory is affected.
        let ptr = unsafe {
            mmap(
                None,
                n,
                ProtFlags::PROT_READ | ProtFlags::PROT_WRITE,
                MapFlags::MAP_SHARED,
                fd,
                0,
            )
        }
        .map_err(|e| io("map a memory file", name, e))?;
        Ok(SharedBuffer {
            ptr,
            len: len.max(1),
            name: name.to_string(),
            fd: Mutex::new(None),
        })
    }

    /// The memory file's descriptor, for a process this one spawns now (see
    /// [`inheritable`]); `None` in a process that mapped the buffer from a descriptor, and
    /// after [`SharedBuffer::close_fd`].
    pub fn raw_fd(&self) -> Option<RawFd> {
        let fd = self.fd.lock().unwrap_or_else(|p| p.into_inner());
        fd.as_ref().map(|f| f.as_raw_fd())
    }

    /// A descriptor of the memory file of its own (`None` as for [`SharedBuffer::raw_fd`]).
    pub fn dup_fd(&self) -> Option<OwnedFd> {
        let fd = self.fd.lock().unwrap_or_else(|p| p.into_inner());
        fd.as_ref().and_then(|f| f.try_clone().ok())
    }

    /// Close the memory file (no more workers to spawn): the mapping stays valid while this
    /// value lives, and its pages go with the last process that maps it.
    pub fn close_fd(&self) {
        self.fd.lock().unwrap_or_else(|p| p.into_inner()).take();
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

/// Make `fds` survive the `exec` of a child: run in the child between `fork` and `exec`
/// (`CommandExt::pre_exec`), so that the descriptors stay closed to every other process the
/// parent starts. Only async-signal-safe calls.
pub fn inheritable(fds: &[RawFd]) -> std::io::Result<()> {
    for &fd in fds {
        // SAFETY: `fcntl` on a descriptor number, async-signal-safe.
        if unsafe { nix::libc::fcntl(fd, nix::libc::F_SETFD, 0) } == -1 {
            return Err(std::io::Error::last_os_error());
        }
    }
    Ok(())
}

/// Take descriptor `raw` handed down by the supervisor (its number on the command line):
/// closed on `exec` from now on, so that what the worker starts does not inherit it.
///
/// # Safety
/// `raw` must be an open descriptor this process owns and nothing else closes.
pub unsafe fn take_inherited(raw: RawFd) -> Result<OwnedFd, IpcError> {
    // SAFETY: the caller's promise.
    let fd = unsafe { <OwnedFd as std::os::fd::FromRawFd>::from_raw_fd(raw) };
    fcntl(&fd, FcntlArg::F_SETFD(FdFlag::FD_CLOEXEC))
        .map_err(|e| io("keep an inherited descriptor from exec", "inherited", e))?;
    debug_assert_eq!(fd.as_raw_fd(), raw);
    Ok(fd)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_buffer_cannot_change_size_and_maps_the_same_pages_twice() {
        let a = SharedBuffer::create("test", 8192).unwrap();
        let fd = a.dup_fd().unwrap();
        for len in [0, 4096, 16384] {
            let e = nix::unistd::ftruncate(&fd, len).unwrap_err();
            assert_eq!(e, nix::errno::Errno::EPERM, "resize to {len}");
        }
        let b = SharedBuffer::from_fd(fd, "test", 8192).unwrap();
        // SAFETY: both map 8192 bytes; only this thread touches them.
        unsafe {
            a.as_ptr().add(4100).write(7);
            assert_eq!(b.as_ptr().add(4100).read(), 7);
        }
        assert!(b.raw_fd().is_none());
        a.close_fd();
        assert!(a.raw_fd().is_none());
        // SAFETY: as above: the mapping outlives the descriptor.
        assert_eq!(unsafe { a.as_ptr().add(4100).read() }, 7);
    }

    #[test]
    fn a_descriptor_that_is_no_sealed_buffer_is_refused() {
        let f = nix::sys::memfd::memfd_create("plain", MFdFlags::MFD_CLOEXEC).unwrap();
        nix::unistd::ftruncate(&f, 4096).unwrap();
        let e = SharedBuffer::from_fd(f, "batch", 4096).unwrap_err();
        assert!(e.to_string().contains("not a sealed memory file"), "{e}");
        let a = SharedBuffer::create("small", 100).unwrap();
        let fd = a.dup_fd().unwrap();
        let e = SharedBuffer::from_fd(fd, "small", 200).unwrap_err();
        assert!(e.to_string().contains("expected 200"), "{e}");
    }
}
