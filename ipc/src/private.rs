//! Private files on a shared machine: the per-user runtime directory that holds every pool, and
//! the exclusive, link-refusing creation of each file and directory a pool makes.
//!
//! Threat model (docs/security.md): other local users are untrusted. They can create names in
//! world-writable directories (`/tmp`, `/dev/shm`) before or while a pool runs, and read
//! anything whose mode lets them. So a pool lives in a directory that only its user can enter
//! ([`resolve_runtime_dir`]), every file is created with `O_CREAT | O_EXCL | O_NOFOLLOW` and
//! mode 0600 ([`create_private_file`]), every directory with mode 0700 and never over an
//! existing name ([`create_private_dir`]), and whatever is read back is checked to be a regular
//! file of this user that nobody else can write ([`open_private_file`]).

use std::fs::{self, DirBuilder, File, Metadata, OpenOptions};
use std::io::{Read, Write};
use std::os::unix::fs::{DirBuilderExt, MetadataExt, OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use nix::libc;

use crate::error::IpcError;

/// Environment variable naming the runtime directory (overrides the default, not an explicit
/// setting).
pub const RUNTIME_DIR_ENV: &str = "ROGUE_GYM_RUNTIME_DIR";

/// Mode bits that open a path to group or others.
const GROUP_OTHER: u32 = 0o077;

fn euid() -> u32 {
    nix::unistd::geteuid().as_raw()
}

fn insecure(path: &Path, reason: impl Into<String>) -> IpcError {
    IpcError::Insecure {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

fn io<'a>(what: &'static str, path: &'a Path) -> impl FnOnce(std::io::Error) -> IpcError + 'a {
    move |source| IpcError::Io {
        what,
        path: path.to_path_buf(),
        source,
    }
}

/// Check that `meta` (from `lstat` or `fstat`) is a `dir`ectory or regular file owned by this
/// user and closed to group and others.
pub fn check_private(path: &Path, meta: &Metadata, dir: bool) -> Result<(), IpcError> {
    let ft = meta.file_type();
    if ft.is_symlink() {
        return Err(insecure(path, "is a symbolic link"));
    }
    if dir && !ft.is_dir() {
        return Err(insecure(path, "is not a directory"));
    }
    if !dir && !ft.is_file() {
        return Err(insecure(path, "is not a regular file"));
    }
    if meta.uid() != euid() {
        return Err(insecure(
            path,
            format!(
                "is owned by uid {}, not by you (uid {})",
                meta.uid(),
                euid()
            ),
        ));
    }
    if meta.mode() & GROUP_OTHER != 0 {
        return Err(insecure(
            path,
            format!(
                "is open to group or others (mode {:04o}; expected {})",
                meta.mode() & 0o7777,
                if dir { "0700" } else { "0600" }
            ),
        ));
    }
    Ok(())
}

/// The parent of a runtime directory must not let another user rename it away: owned by this
/// user or root, and sticky if others may write to it.
fn check_parent(dir: &Path) -> Result<(), IpcError> {
    let Some(parent) = dir.parent().filter(|p| !p.as_os_str().is_empty()) else {
        return Ok(());
    };
    let meta = fs::metadata(parent).map_err(io("inspect runtime directory parent", parent))?;
    let owner_ok = meta.uid() == euid() || meta.uid() == 0;
    let writable_by_others = meta.mode() & 0o022 != 0;
    let sticky = meta.mode() & 0o1000 != 0;
    if !owner_ok || (writable_by_others && !sticky) {
        return Err(insecure(
            dir,
            format!(
                "sits in {} (owner uid {}, mode {:04o}), where another user could replace it",
                parent.display(),
                meta.uid(),
                meta.mode() & 0o7777
            ),
        ));
    }
    Ok(())
}

/// Create `dir` (mode 0700) if it is missing, then check that it is a real directory (not a
/// link) owned by this user, closed to group and others, in a parent nobody else can swap it
/// in. Its parent must exist.
pub fn ensure_private_dir(dir: &Path) -> Result<(), IpcError> {
    if !dir.is_absolute() {
        return Err(insecure(dir, "is not an absolute path"));
    }
    match DirBuilder::new().mode(0o700).create(dir) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(source) => {
            return Err(IpcError::Io {
                what: "create runtime directory",
                path: dir.to_path_buf(),
                source,
            });
        }
    }
    let meta = fs::symlink_metadata(dir).map_err(io("inspect runtime directory", dir))?;
    check_private(dir, &meta, true)?;
    check_parent(dir)
}

/// The default runtime directory: `$ROGUE_GYM_RUNTIME_DIR`, else
/// `$XDG_RUNTIME_DIR/rogue-gym`, else `/tmp/rogue-gym-<uid>`.
pub fn default_runtime_dir() -> PathBuf {
    if let Some(d) = std::env::var_os(RUNTIME_DIR_ENV).filter(|d| !d.is_empty()) {
        return PathBuf::from(d);
    }
    if let Some(d) = std::env::var_os("XDG_RUNTIME_DIR").filter(|d| !d.is_empty()) {
        let d = PathBuf::from(d);
        if d.is_absolute() {
            return d.join("rogue-gym");
        }
    }
    PathBuf::from(format!("/tmp/rogue-gym-{}", euid()))
}

/// A fresh private directory `/tmp/rogue-gym-<uid>-XXXXXX` for this process, made once: the
/// stand-in when someone else holds the default `/tmp` name.
fn fallback_runtime_dir() -> Result<PathBuf, IpcError> {
    static FALLBACK: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    FALLBACK
        .get_or_init(|| {
            let template = format!("/tmp/rogue-gym-{}-XXXXXX", euid());
            nix::unistd::mkdtemp(template.as_str()).map_err(|e| format!("{template}: {e}"))
        })
        .clone()
        .map_err(|e| IpcError::InvalidName(format!("cannot create a private directory {e}")))
}

/// The runtime directory a pool uses, created and verified ([`ensure_private_dir`]).
///
/// `explicit` (a setting) wins, then [`default_runtime_dir`]. An explicit directory, the
/// environment variable's and `$XDG_RUNTIME_DIR`'s must pass the checks, or this is an error
/// that says what is wrong. Only the shared `/tmp/rogue-gym-<uid>` default, which any user can
/// plant first, is bypassed when it fails them: the process then uses a fresh private
/// `/tmp/rogue-gym-<uid>-XXXXXX` and says so on stderr once.
pub fn resolve_runtime_dir(explicit: Option<&Path>) -> Result<PathBuf, IpcError> {
    let (dir, shared_default) = match explicit {
        Some(d) => (d.to_path_buf(), false),
        None => {
            let d = default_runtime_dir();
            let shared = d == Path::new(&format!("/tmp/rogue-gym-{}", euid()));
            (d, shared)
        }
    };
    match ensure_private_dir(&dir) {
        Ok(()) => Ok(dir),
        Err(e @ IpcError::Insecure { .. }) if shared_default => {
            static WARNED: std::sync::Once = std::sync::Once::new();
            let fallback = fallback_runtime_dir()?;
            WARNED.call_once(|| {
                eprintln!(
                    "rogue-gym: not using {}: {e}; using the private {} instead (set {RUNTIME_DIR_ENV} to choose)",
                    dir.display(),
                    fallback.display()
                )
            });
            ensure_private_dir(&fallback)?;
            Ok(fallback)
        }
        Err(e) => Err(e),
    }
}

/// Create directory `path` with mode 0700; an existing name (directory, file or link) is an
/// error, never reused.
pub fn create_private_dir(path: &Path) -> Result<(), IpcError> {
    DirBuilder::new()
        .mode(0o700)
        .create(path)
        .map_err(io("create private directory", path))
}

/// Create file `path` with mode 0600, exclusively (`O_EXCL`) and without following a link
/// (`O_NOFOLLOW`): an existing name is an error, never reused or written through.
pub fn create_private_file(path: &Path) -> Result<File, IpcError> {
    let f = OpenOptions::new()
        .read(true)
        .write(true)
        .create_new(true)
        .mode(0o600)
        .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC)
        .open(path)
        .map_err(io("create private file", path))?;
    // The umask can only have removed bits; make the mode exact.
    f.set_permissions(fs::Permissions::from_mode(0o600))
        .map_err(io("set private file mode", path))?;
    Ok(f)
}

/// Write `data` to `path` atomically: to `<path>.tmp` (created by [`create_private_file`], a
/// stale one from a crash removed first), then renamed over `path`, so a reader never sees
/// half a file. For paths inside a private directory only.
pub fn write_private_file(path: &Path, data: &[u8]) -> Result<(), IpcError> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    remove_if_present(&tmp, "remove stale temporary file")?;
    let mut f = create_private_file(&tmp)?;
    f.write_all(data).map_err(io("write private file", &tmp))?;
    fs::rename(&tmp, path).map_err(io("rename private file", path))
}

/// `lstat` of `path` (a link itself, never its target): `None` where nothing is there.
pub fn lstat_if_present(path: &Path, what: &'static str) -> Result<Option<Metadata>, IpcError> {
    match fs::symlink_metadata(path) {
        Ok(meta) => Ok(Some(meta)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(source) => Err(IpcError::Io {
            what,
            path: path.to_path_buf(),
            source,
        }),
    }
}

/// Remove file `path` (a link itself, never its target); a missing file is not an error.
pub fn remove_if_present(path: &Path, what: &'static str) -> Result<(), IpcError> {
    match fs::remove_file(path) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(source) => Err(IpcError::Io {
            what,
            path: path.to_path_buf(),
            source,
        }),
    }
}

/// Open an existing file for reading without following a link, and check that it is a regular
/// file of this user that group and others cannot touch ([`check_private`]).
pub fn open_private_file(path: &Path) -> Result<File, IpcError> {
    let f = OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC)
        .open(path)
        .map_err(io("open private file", path))?;
    let meta = f.metadata().map_err(io("inspect private file", path))?;
    check_private(path, &meta, false)?;
    Ok(f)
}

/// [`open_private_file`], for reading and writing.
pub fn open_private_file_rw(path: &Path) -> Result<File, IpcError> {
    let f = OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC)
        .open(path)
        .map_err(io("open private file", path))?;
    let meta = f.metadata().map_err(io("inspect private file", path))?;
    check_private(path, &meta, false)?;
    Ok(f)
}

/// Read a whole file opened by [`open_private_file`].
pub fn read_private_file(path: &Path) -> Result<Vec<u8>, IpcError> {
    let mut data = Vec::new();
    open_private_file(path)?
        .read_to_end(&mut data)
        .map_err(io("read private file", path))?;
    Ok(data)
}

/// Clear the group and other bits of every file and directory under `dir` (itself included)
/// that this user owns, without following links: iceoryx2 makes some of its directories 0750
/// and files 0640. They sit inside a 0700 directory already; this makes each mode say so too.
pub fn tighten_tree(dir: &Path) -> Result<(), IpcError> {
    let meta = match fs::symlink_metadata(dir) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(source) => {
            return Err(IpcError::Io {
                what: "inspect pool directory",
                path: dir.to_path_buf(),
                source,
            });
        }
    };
    if meta.file_type().is_symlink() || meta.uid() != euid() {
        return Ok(());
    }
    let mode = meta.mode() & 0o7777;
    if mode & GROUP_OTHER != 0 {
        // A file removed in between (a node going away) is fine.
        let _ = fs::set_permissions(dir, fs::Permissions::from_mode(mode & !GROUP_OTHER));
    }
    if meta.is_dir()
        && let Ok(rd) = fs::read_dir(dir)
    {
        for e in rd.flatten() {
            tighten_tree(&e.path())?;
        }
    }
    Ok(())
}

/// 64 bits from the kernel's random source, for names nobody can guess.
pub fn random_u64() -> Result<u64, IpcError> {
    let path = Path::new("/dev/urandom");
    let mut b = [0u8; 8];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut b))
        .map_err(io("read random bytes", path))?;
    Ok(u64::from_le_bytes(b))
}
