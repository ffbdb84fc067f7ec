//! The ledger of this user's live pools on this machine: one private file per pool in
//! `RUNTIME/ledger/`, saying its supervisor's process, how many workers it runs, whether its
//! caller polls for answers, and the cores it pinned its workers to. Each pool decides how to
//! wait (poll or block, caller and workers) from the whole machine's booking, not from its own
//! workers alone, and pools asked for disjoint cores take them here.
//!
//! Same rules as every file of a pool: the directory is private (0700, a real directory of this
//! user), each entry a private file created exclusively and replaced by rename, never read
//! through a link or from another user. An entry whose process is gone (a pool killed with
//! SIGKILL) is ignored and removed by the next reader. Other users' pools are in their own
//! runtime directories: a user's ledger sees its own pools only.

use std::fs;
use std::path::{Path, PathBuf};

use crate::error::IpcError;
use crate::naming::process_start_time;
use crate::private::{
    ensure_private_dir, read_private_file, remove_if_present, write_private_file,
};

/// The ledger's directory in a runtime directory.
const DIR: &str = "ledger";
/// The lock taken while cores are handed out.
const LOCK: &str = ".lock";

/// One live pool.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entry {
    /// The pool's name.
    pub pool: String,
    /// Its supervisor's process, and when that process started (so that a recycled pid is not
    /// taken for it).
    pub pid: u32,
    /// Start time of `pid` (`/proc/<pid>/stat`, clock ticks since boot).
    pub start: u64,
    /// Its workers.
    pub workers: usize,
    /// Its caller polls for answers (it takes a core while it waits).
    pub caller_polls: bool,
    /// The cores its workers are pinned to (empty: the kernel places them).
    pub cores: Vec<usize>,
}

impl Entry {
    /// The entry of a pool of this process.
    pub fn of_this_process(
        pool: &str,
        workers: usize,
        caller_polls: bool,
        cores: Vec<usize>,
    ) -> Self {
        let pid = std::process::id();
        Entry {
            pool: pool.to_string(),
            pid,
            start: process_start_time(pid).unwrap_or(0),
            workers,
            caller_polls,
            cores,
        }
    }

    fn encode(&self) -> String {
        let cores: Vec<String> = self.cores.iter().map(ToString::to_string).collect();
        format!(
            "pid={} start={} workers={} caller_polls={} cores={}\n",
            self.pid,
            self.start,
            self.workers,
            u8::from(self.caller_polls),
            cores.join(",")
        )
    }

    fn decode(pool: &str, text: &str) -> Option<Entry> {
        let mut e = Entry {
            pool: pool.to_string(),
            pid: 0,
            start: 0,
            workers: 0,
            caller_polls: false,
            cores: Vec::new(),
        };
        for field in text.split_whitespace() {
            let (k, v) = field.split_once('=')?;
            match k {
                "pid" => e.pid = v.parse().ok()?,
                "start" => e.start = v.parse().ok()?,
                "workers" => e.workers = v.parse().ok()?,
                "caller_polls" => e.caller_polls = v == "1",
                "cores" if !v.is_empty() => {
                    e.cores = v
                        .split(',')
                        .map(str::parse)
                        .collect::<Result<_, _>>()
                        .ok()?
                }
                _ => {}
            }
        }
        (e.pid != 0).then_some(e)
    }

    /// Whether its process still runs (the same process: its start time matches).
    fn alive(&self) -> bool {
        process_start_time(self.pid).is_some_and(|s| s == self.start)
    }
}

/// A user's ledger (see the module docs).
#[derive(Debug, Clone)]
pub struct Ledger {
    dir: PathBuf,
}

impl Ledger {
    /// The ledger of runtime directory `runtime_dir` (already verified private), its directory
    /// created 0700 if missing and refused if it is a link, another user's, or open to others.
    pub fn open(runtime_dir: &Path) -> Result<Ledger, IpcError> {
        let dir = runtime_dir.join(DIR);
        ensure_private_dir(&dir)?;
        Ok(Ledger { dir })
    }

    /// Record (or update) `entry`.
    pub fn write(&self, entry: &Entry) -> Result<(), IpcError> {
        write_private_file(&self.dir.join(&entry.pool), entry.encode().as_bytes())
    }

    /// Remove pool `pool`'s entry (a missing one is no error).
    pub fn remove(&self, pool: &str) -> Result<(), IpcError> {
        remove_if_present(&self.dir.join(pool), "remove a ledger entry")
    }

    /// The live pools, in name order. Entries of processes that are gone are removed; files
    /// that are not private files of this user, or not entries, are skipped.
    pub fn read(&self) -> Vec<Entry> {
        let Ok(dir) = fs::read_dir(&self.dir) else {
            return Vec::new();
        };
        let mut out = Vec::new();
        for f in dir.flatten() {
            let name = f.file_name().to_string_lossy().into_owned();
            if name.starts_with('.') || name.ends_with(".tmp") {
                continue;
            }
            let Ok(data) = read_private_file(&f.path()) else {
                continue;
            };
            let Some(e) = Entry::decode(&name, &String::from_utf8_lossy(&data)) else {
                continue;
            };
            if e.alive() {
                out.push(e);
            } else {
                let _ = fs::remove_file(f.path());
            }
        }
        out.sort_by(|a, b| a.pool.cmp(&b.pool));
        out
    }

    /// Hold the ledger's lock (released when the value drops): cores are handed out under it,
    /// so that two pools starting together never take the same.
    pub fn lock(&self) -> Result<LedgerLock, IpcError> {
        let path = self.dir.join(LOCK);
        let file = match crate::private::open_private_file_rw(&path) {
            Ok(f) => f,
            Err(_) => crate::private::create_private_file(&path)
                .or_else(|_| crate::private::open_private_file_rw(&path))?,
        };
        let lock = nix::fcntl::Flock::lock(file, nix::fcntl::FlockArg::LockExclusive).map_err(
            |(_, e)| IpcError::Io {
                what: "lock the pool ledger",
                path: path.clone(),
                source: std::io::Error::from(e),
            },
        )?;
        Ok(LedgerLock { _lock: lock })
    }
}

/// The ledger's lock, held while it lives.
pub struct LedgerLock {
    _lock: nix::fcntl::Flock<fs::File>,
}

/// The first `n` of `usable` cores that no pool in `taken` holds, or `None` when fewer are free.
pub fn free_cores(usable: &[usize], taken: &[Entry], n: usize) -> Option<Vec<usize>> {
    let held: Vec<usize> = taken.iter().flat_map(|e| e.cores.iter().copied()).collect();
    let free: Vec<usize> = usable
        .iter()
        .copied()
        .filter(|c| !held.contains(c))
        .collect();
    (free.len() >= n).then(|| free[..n].to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn private_base(name: &str) -> PathBuf {
        let base = std::env::temp_dir().join(format!("{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&base);
        ensure_private_dir(&base).unwrap();
        base
    }

    #[test]
    fn entries_round_trip_and_a_dead_pools_entry_is_ignored_and_swept() {
        let base = private_base("rg-ledger");
        let l = Ledger::open(&base).unwrap();
        let me = Entry::of_this_process("rgaaaa", 2, true, vec![0, 1]);
        l.write(&me).unwrap();
        let dead = Entry {
            pid: u32::MAX - 1,
            ..Entry::of_this_process("rgbbbb", 4, false, Vec::new())
        };
        l.write(&dead).unwrap();
        // A recycled pid: the process is alive but started at another time.
        let recycled = Entry {
            start: me.start + 1,
            ..Entry::of_this_process("rgcccc", 1, false, Vec::new())
        };
        l.write(&recycled).unwrap();
        assert_eq!(l.read(), vec![me.clone()]);
        assert!(!base.join(DIR).join("rgbbbb").exists(), "swept");
        assert!(!base.join(DIR).join("rgcccc").exists(), "swept");
        l.remove("rgaaaa").unwrap();
        assert_eq!(l.read(), vec![]);
        let _lock = l.lock().unwrap();
        fs::remove_dir_all(&base).unwrap();
    }

    #[test]
    fn a_linked_or_open_ledger_is_refused_and_loose_entries_are_skipped() {
        use std::os::unix::fs::PermissionsExt;
        let base = private_base("rg-ledger-bad");
        let elsewhere = base.join("elsewhere");
        fs::create_dir(&elsewhere).unwrap();
        std::os::unix::fs::symlink(&elsewhere, base.join(DIR)).unwrap();
        assert!(Ledger::open(&base).is_err(), "a link is no ledger");
        fs::remove_file(base.join(DIR)).unwrap();
        fs::create_dir(base.join(DIR)).unwrap();
        fs::set_permissions(base.join(DIR), fs::Permissions::from_mode(0o755)).unwrap();
        assert!(
            Ledger::open(&base).is_err(),
            "a ledger open to others is refused"
        );
        fs::set_permissions(base.join(DIR), fs::Permissions::from_mode(0o700)).unwrap();
        let l = Ledger::open(&base).unwrap();
        let loose = base.join(DIR).join("rgdddd");
        fs::write(
            &loose,
            Entry::of_this_process("rgdddd", 9, true, vec![]).encode(),
        )
        .unwrap();
        fs::set_permissions(&loose, fs::Permissions::from_mode(0o644)).unwrap();
        std::os::unix::fs::symlink(&loose, base.join(DIR).join("rgeeee")).unwrap();
        assert_eq!(l.read(), vec![], "a loose file and a link are no entries");
        fs::remove_dir_all(&base).unwrap();
    }

    #[test]
    fn free_cores_are_the_first_no_pool_holds() {
        let a = Entry::of_this_process("a", 2, false, vec![0, 1]);
        let b = Entry::of_this_process("b", 1, false, vec![3]);
        assert_eq!(
            free_cores(&[0, 1, 2, 3, 4], &[a.clone(), b.clone()], 2),
            Some(vec![2, 4])
        );
        assert_eq!(free_cores(&[0, 1, 2, 3], &[a, b], 2), None);
    }
}
