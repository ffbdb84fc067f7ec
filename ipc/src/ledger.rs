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
//!
//! The directory exists while pools do: the first pool creates it under its lock, and the last
//! to leave removes it, lock file and all, so a closed run leaves its runtime directory empty.
//! A lock taken on a lock file that was removed meanwhile is taken again on the new one.

use std::fs;
use std::path::{Path, PathBuf};

use crate::error::IpcError;
use crate::naming::process_start_time;
use crate::private::{
    check_private, ensure_private_dir, lstat_if_present, read_private_file, remove_if_present,
    write_private_file,
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
    /// The ledger of runtime directory `runtime_dir` (already verified private). Its directory,
    /// where it exists, is refused if it is a link, another user's, or open to others; a
    /// missing one is an empty ledger ([`Ledger::lock`] creates it).
    pub fn open(runtime_dir: &Path) -> Result<Ledger, IpcError> {
        let dir = runtime_dir.join(DIR);
        if let Some(meta) = lstat_if_present(&dir, "inspect the pool ledger")? {
            check_private(&dir, &meta, true)?;
        }
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

    /// Hold the ledger's lock (released when the value drops), its directory created 0700 if
    /// missing: cores are handed out under it, so that two pools starting together never take
    /// the same, and the last pool to leave removes the directory under it.
    pub fn lock(&self) -> Result<LedgerLock, IpcError> {
        use std::os::unix::fs::MetadataExt;
        let path = self.dir.join(LOCK);
        let mut tries = 0;
        loop {
            tries += 1;
            // The directory and its lock file may be removed by a pool leaving meanwhile
            // ([`Ledger::leave`]): then again, a bounded number of times.
            let opened = ensure_private_dir(&self.dir).and_then(|()| {
                crate::private::open_private_file_rw(&path).or_else(|_| {
                    crate::private::create_private_file(&path)
                        .or_else(|_| crate::private::open_private_file_rw(&path))
                })
            });
            let file = match opened {
                Ok(f) => f,
                Err(e) if tries >= LOCK_TRIES => return Err(e),
                Err(_) => continue,
            };
            let lock = nix::fcntl::Flock::lock(file, nix::fcntl::FlockArg::LockExclusive).map_err(
                |(_, e)| IpcError::Io {
                    what: "lock the pool ledger",
                    path: path.clone(),
                    source: std::io::Error::from(e),
                },
            )?;
            // Locked: still the ledger's lock file, not one a leaving pool removed?
            let held = lock.metadata().map(|m| (m.dev(), m.ino()));
            let named = fs::symlink_metadata(&path).map(|m| (m.dev(), m.ino()));
            match (held, named) {
                (Ok(h), Ok(n)) if h == n => return Ok(LedgerLock { _lock: lock }),
                _ if tries >= LOCK_TRIES => {
                    return Err(IpcError::Io {
                        what: "lock the pool ledger (its lock file kept changing)",
                        path,
                        source: std::io::Error::from(std::io::ErrorKind::WouldBlock),
                    });
                }
                _ => {}
            }
        }
    }

    /// Remove pool `pool`'s entry and, when no other entry is left, the ledger's directory
    /// (under its lock, so that no pool joins meanwhile).
    pub fn leave(&self, pool: &str) -> Result<(), IpcError> {
        self.remove(pool)?;
        if !self.dir.exists() {
            return Ok(());
        }
        let _lock = self.lock()?;
        let others = fs::read_dir(&self.dir)
            .map(|d| d.flatten().any(|f| f.file_name() != LOCK))
            .unwrap_or(true);
        if !others {
            remove_if_present(&self.dir.join(LOCK), "remove the ledger's lock")?;
            // A file written meanwhile (a temporary of a live pool's entry) keeps it: no error.
            let _ = fs::remove_dir(&self.dir);
        }
        Ok(())
    }
}

/// How many times [`Ledger::lock`] tries before it gives up.
const LOCK_TRIES: u32 = 100;

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
        drop(l.lock().unwrap()); // creates the directory
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
        fs::remove_dir_all(&base).unwrap();
    }

    #[test]
    fn the_last_pool_to_leave_removes_the_ledger_and_the_next_makes_it_again() {
        let base = private_base("rg-ledger-leave");
        let l = Ledger::open(&base).unwrap();
        assert!(!base.join(DIR).exists(), "opening creates nothing");
        for pool in ["rgaaaa", "rgbbbb"] {
            let _lock = l.lock().unwrap();
            l.write(&Entry::of_this_process(pool, 1, false, vec![]))
                .unwrap();
        }
        l.leave("rgaaaa").unwrap();
        assert_eq!(l.read().len(), 1, "another pool keeps the ledger");
        l.leave("rgbbbb").unwrap();
        assert!(!base.join(DIR).exists(), "the last one removed it");
        // A pool waiting on the lock file that the last one removed takes it again on the new.
        let held = l.lock().unwrap();
        let (l2, dir) = (l.clone(), base.join(DIR));
        let waiter = std::thread::spawn(move || {
            use std::os::unix::fs::MetadataExt;
            let lock = l2.lock().unwrap();
            let ino = fs::metadata(dir.join(LOCK)).unwrap().ino();
            drop(lock);
            ino
        });
        std::thread::sleep(std::time::Duration::from_millis(200));
        fs::remove_file(base.join(DIR).join(LOCK)).unwrap();
        fs::remove_dir(base.join(DIR)).unwrap();
        drop(held);
        let ino = waiter.join().unwrap();
        let _again = l.lock().unwrap();
        use std::os::unix::fs::MetadataExt;
        assert_eq!(ino, fs::metadata(base.join(DIR).join(LOCK)).unwrap().ino());
        assert!(base.join(DIR).join(LOCK).exists());
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
