//! Cleanup: removing a pool's `/dev/shm` files and directories, sweeping pools whose owner
//! died, and removing dead iceoryx2 nodes.

use std::fs;
use std::os::unix::fs::MetadataExt;
use std::path::Path as StdPath;
use std::time::Duration;

use iceoryx2::prelude::*;

use crate::Svc;
use crate::error::IpcError;
use crate::error::ice;
use crate::naming::{PoolId, pool_shm_files, process_start_time};
use crate::private::check_private;

/// Remove every file of a pool: `/dev/shm/<prefix>*` (including iceoryx2's `*.global_mgmt`
/// counter), the iceoryx2 root and the pool's own directory. Call only once no process of the
/// pool is alive. Missing files are not an error; files of other users are left alone (and
/// links are removed, never followed).
pub fn remove_pool_files(id: &PoolId) -> Result<(), IpcError> {
    let me = nix::unistd::geteuid().as_raw();
    for p in pool_shm_files(id) {
        if fs::symlink_metadata(&p).is_ok_and(|m| m.uid() != me) {
            continue;
        }
        crate::private::remove_if_present(&p, "remove shared-memory file")?;
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

/// Whether the owner recorded in a pool's owner file is still running. The file must be a
/// private file of this user ([`crate::private::read_private_file`]); `None` if it is missing or not.
fn owner_alive(id: &PoolId) -> Option<bool> {
    let data = crate::private::read_private_file(&id.aux_dir().join("owner")).ok()?;
    let s = String::from_utf8_lossy(&data);
    let mut it = s.split_whitespace();
    let (Some(Ok(pid)), Some(Ok(start))) = (
        it.next().map(str::parse::<u32>),
        it.next().map(str::parse::<u64>),
    ) else {
        return None;
    };
    Some(match process_start_time(pid) {
        Some(t) => start == 0 || t == start,
        None => false,
    })
}

/// A pool whose owner file is not written yet (missing, or created and not yet filled in) but
/// whose directory is only seconds old is being created by a live process: leave it alone.
fn young_without_owner(id: &PoolId) -> bool {
    if owner_alive(id).is_some() {
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

pub(crate) fn is_pool_name(s: &str) -> bool {
    s.len() == 2 + crate::naming::NAME_HEX_DIGITS
        && s.starts_with("rg")
        && s[2..].bytes().all(|b| b.is_ascii_hexdigit())
}

/// Whether `path` is a directory of this user closed to others (not a link).
fn own_private_dir(path: &StdPath) -> bool {
    fs::symlink_metadata(path).is_ok_and(|m| check_private(path, &m, true).is_ok())
}

/// Remove the files of every pool in the runtime directory `base` whose owner process is dead
/// (pools left behind by a killed supervisor). A pool's aux directory (with the owner file) is
/// created before and removed after all its other files, so every leftover is found through
/// it. Only pools of this user are touched: `base` must be a private directory of this user,
/// and each pool's directories and owner file must be too; nothing is followed through a
/// link. Returns the names of the pools removed. Safe to run while other live pools exist.
pub fn sweep_stale_pools(base: &StdPath) -> Vec<String> {
    let mut removed = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    if !own_private_dir(base) {
        return removed;
    }
    if let Ok(rd) = fs::read_dir(base) {
        for e in rd.flatten() {
            let fname = e.file_name().to_string_lossy().into_owned();
            let name = fname.strip_suffix(".d").unwrap_or(&fname).to_string();
            if !is_pool_name(&name) || !seen.insert(name.clone()) {
                continue;
            }
            if let Ok(id) = PoolId::from_parts(&name, base) {
                // A pool creates its aux dir (with the owner file) before anything else.
                let dirs = [id.aux_dir(), id.root()];
                if dirs.iter().any(|d| d.exists() && !own_private_dir(d)) {
                    continue; // not this user's pool, or not one it made: leave it alone
                }
                if young_without_owner(&id) {
                    continue; // being created right now
                }
                if owner_alive(&id) != Some(true) && remove_pool_files(&id).is_ok() {
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
