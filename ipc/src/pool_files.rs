//! The pool's own shared-memory files kept private: iceoryx2's node counter, which iceoryx2
//! would make world-writable, created first by the pool ([`create_node_counter`]), and every
//! file of the pool audited once its workers are up ([`verify_pool_files`]).

use std::io::Write;
use std::path::Path as StdPath;

use crate::cleanup::remove_pool_files;
use crate::error::IpcError;
use crate::naming::{PoolId, SHM_DIR, pool_shm_files};
use crate::private::{
    check_private, create_private_dir, create_private_file, lstat_if_present, tighten_tree,
};

/// iceoryx2's per-root node counter (`/dev/shm/<prefix><type hash>_node.<version>.global_mgmt`):
/// the first node of a root creates it world-writable (mode 0666). Create it first,
/// exclusively and 0600, initialised as iceoryx2 initialises it (its version word, then a
/// zero counter), so that iceoryx2 opens ours and no other user ever can. The first call of
/// a process learns the counter's name (see `node_counter_name`).
pub fn create_node_counter(id: &PoolId) -> Result<(), IpcError> {
    let v = iceoryx2_bb_elementary::package_version::PackageVersion::get();
    let path = node_counter_path(id)?;
    let mut f = create_private_file(&path)?;
    // Layout of iceoryx2's `Data<State>` (repr C): a u64 version, then a u32 counter,
    // padded to 16 bytes.
    let mut bytes = [0u8; 16];
    bytes[..8].copy_from_slice(&v.to_u64().to_ne_bytes());
    f.write_all(&bytes).map_err(|source| IpcError::Io {
        what: "write node counter",
        path: path.clone(),
        source,
    })
}

/// Where iceoryx2's node counter of pool `id` lies (see [`create_node_counter`]).
pub fn node_counter_path(id: &PoolId) -> Result<std::path::PathBuf, IpcError> {
    Ok(StdPath::new(SHM_DIR).join(format!("{}{}", id.prefix(), node_counter_name(id.base())?)))
}

/// Check every file of this user under the pool's prefix in `/dev/shm` (a regular file
/// closed to group and others), and clear group and other bits in the pool's directories
/// ([`tighten_tree`]). The supervisor runs it once its workers are up.
///
/// Names someone else planted under the prefix are left alone: every name the pool opens
/// rather than creates is its own already (the node counter, [`create_node_counter`];
/// iceoryx2 creates each of its other `/dev/shm` files exclusively), so a planted name can
/// at most make a creation fail, never feed the pool.
pub fn verify_pool_files(id: &PoolId) -> Result<(), IpcError> {
    let me = nix::unistd::geteuid().as_raw();
    for p in pool_shm_files(id) {
        match lstat_if_present(&p, "inspect shared-memory file")? {
            Some(m) if std::os::unix::fs::MetadataExt::uid(&m) != me => {}
            Some(m) => check_private(&p, &m, false)?,
            None => {}
        }
    }
    tighten_tree(&id.root())?;
    tighten_tree(&id.aux_dir())
}

/// The name of iceoryx2's node counter after a root's prefix. It holds a hash of a Rust type
/// name, so it is learnt once per process: a throwaway node in a throwaway root (in the private
/// runtime directory `base`) makes one, whose name is read and whose files are removed.
fn node_counter_name(base: &StdPath) -> Result<String, IpcError> {
    static NAME: std::sync::OnceLock<Result<String, String>> = std::sync::OnceLock::new();
    NAME.get_or_init(|| {
        let probe = PoolId::new_unique(base).map_err(|e| e.to_string())?;
        create_private_dir(&probe.root()).map_err(|e| e.to_string())?;
        let learnt = probe
            .node("probe")
            .map(drop)
            .map_err(|e| e.to_string())
            .and_then(|()| {
                pool_shm_files(&probe)
                    .iter()
                    .filter_map(|p| {
                        p.file_name()?
                            .to_str()?
                            .strip_prefix(&probe.prefix())
                            .map(str::to_string)
                    })
                    .find(|n| n.ends_with(".global_mgmt"))
                    .ok_or_else(|| "iceoryx2 made no node counter".to_string())
            });
        let _ = remove_pool_files(&probe);
        learnt
    })
    .clone()
    .map_err(|e| IpcError::InvalidName(format!("cannot learn iceoryx2's node counter name: {e}")))
}
