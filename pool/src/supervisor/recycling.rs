//! Planned replacement of workers, for envs that leak: `recycle_after_steps` (env steps a
//! worker serves) and `recycle_above_rss` (its resident memory).
//!
//! A worker near its bound ([`START_AT`]) first gets a *successor*: a process of its next generation that
//! builds the envs while the old worker goes on serving, and creates its marker file
//! ([`successor_marker`]) once they are built. At the worker's first command boundary at its
//! bound, the supervisor closes the old worker and tells the successor to go on
//! ([`successor_go`]), which opens the worker's ports and says it is ready; the
//! envs' episodes are cut there, and the command that follows resets them (`truncated`, with
//! the info `worker_recycled`). Every transition the old worker served was delivered. Planned
//! replacements are counted apart from crash restarts (`recycles` in the statistics) and use
//! none of the restart budget. A successor that dies or does not build its envs within
//! `start_timeout` is dropped; the old worker serves on, and a new successor is tried after a
//! pause.

use std::fs;
use std::process::Child;
use std::time::{Duration, Instant};

use super::Supervisor;
use crate::error::PoolError;
use crate::wire::{Command, Op, successor_go, successor_marker};

/// How often a worker's resident memory is read (`/proc/<pid>/statm`, about 10 µs) while it
/// is below [`START_AT`] of its bound, at most; above, it is read before every command.
const RSS_EVERY: Duration = Duration::from_millis(5);
/// The share of its bound at which a worker's successor starts building its envs, so that it
/// is ready when the worker reaches the bound.
const START_AT: f64 = 0.75;
/// How long a closed worker gets to exit before it is killed.
const CLOSE_WITHIN: Duration = Duration::from_secs(2);

/// A worker's successor while it builds its envs.
pub(super) struct Successor {
    pub(super) child: Child,
    pub(super) generation: u64,
    pub(super) since: Instant,
    pub(super) stderr_path: std::path::PathBuf,
}

/// Resident memory of process `pid`, in bytes.
fn rss_bytes(pid: u32) -> Option<u64> {
    let statm = fs::read_to_string(format!("/proc/{pid}/statm")).ok()?;
    let pages: u64 = statm.split_whitespace().nth(1)?.parse().ok()?;
    let page = nix::unistd::sysconf(nix::unistd::SysconfVar::PAGE_SIZE)
        .ok()
        .flatten()
        .unwrap_or(4096) as u64;
    Some(pages * page)
}

/// Stop `child`: it was asked to close; wait up to `within`, then kill it.
fn reap(mut child: Child, within: Duration) {
    let deadline = Instant::now() + within;
    loop {
        match child.try_wait() {
            Ok(Some(_)) => return,
            Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(1)),
            _ => {
                let _ = child.kill();
                let _ = child.wait();
                return;
            }
        }
    }
}

impl Supervisor {
    /// Whether recycling is on at all.
    fn recycling(&self) -> bool {
        self.cfg.recycle_after_steps.is_some() || self.cfg.recycle_above_rss.is_some()
    }

    /// How far worker `k` is toward its bound: its served steps and its resident memory after
    /// one more command (growing as it last grew), each over its bound, the larger (1.0: at
    /// the bound).
    fn progress(&mut self, k: usize) -> f64 {
        let s = &mut self.workers[k];
        let mut p = 0.0f64;
        if let Some(n) = self.cfg.recycle_after_steps {
            p = s.served as f64 / n.max(1) as f64;
        }
        if let Some(limit) = self.cfg.recycle_above_rss {
            // Read at every boundary once near the bound, else now and then.
            let near = s.rss as f64 >= START_AT * limit as f64;
            if near || s.rss_read.is_none_or(|t| t.elapsed() >= RSS_EVERY) {
                s.rss_read = Some(Instant::now());
                let rss = rss_bytes(s.pid).unwrap_or(0);
                s.rss_growth = rss.saturating_sub(s.rss);
                s.rss = rss;
            }
            // What it will hold after one more command, if it grows as it just did.
            p = p.max((s.rss + s.rss_growth) as f64 / limit.max(1) as f64);
        }
        p
    }

    /// Worker `k` is idle before its next command. From [`START_AT`] of its bound on it gets a
    /// successor; at its bound it is replaced by that successor (waiting for its envs to be
    /// built if they are not yet: a leak faster than a start-up stalls this worker, never
    /// breaks the bound). Returns whether `k` was replaced: it is then starting, and its next
    /// command resets its envs.
    pub(super) fn recycle_if_due(&mut self, k: usize) -> Result<bool, PoolError> {
        if !self.recycling() || !self.workers[k].state.is_idle() {
            return Ok(false);
        }
        let progress = self.progress(k);
        if self.workers[k].successor.is_none() {
            let paused = self.workers[k]
                .recycle_pause
                .is_some_and(|t| Instant::now() < t);
            if progress < START_AT || paused {
                return Ok(false);
            }
            self.start_successor(k)?;
        }
        if progress < 1.0 {
            if let Some(why) = self.successor_failed(k) {
                self.drop_successor(k, Some(why));
            }
            return Ok(false);
        }
        loop {
            if let Some(why) = self.successor_failed(k) {
                self.drop_successor(k, Some(why));
                return Ok(false);
            }
            let generation = self.workers[k]
                .successor
                .as_ref()
                .map_or(0, |s| s.generation);
            if successor_marker(&self.id, k, generation).exists() {
                self.hand_over(k)?;
                return Ok(true);
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Why worker `k`'s successor is of no use, if it is not: it exited, or did not build its
    /// envs within `start_timeout`.
    fn successor_failed(&mut self, k: usize) -> Option<&'static str> {
        let succ = self.workers[k].successor.as_mut()?;
        if !matches!(succ.child.try_wait(), Ok(None)) {
            Some("exited while building its envs")
        } else if succ.since.elapsed() > self.cfg.start_timeout {
            Some("did not build its envs within start_timeout")
        } else {
            None
        }
    }

    fn start_successor(&mut self, k: usize) -> Result<(), PoolError> {
        let generation = self.workers[k].generation + 1;
        let (child, stderr_path) = self.start_process(k, generation, true)?;
        self.workers[k].successor = Some(Successor {
            child,
            generation,
            since: Instant::now(),
            stderr_path,
        });
        Ok(())
    }

    /// Stop worker `k`'s successor, if any (`why`: it failed, said in the statistics, and the
    /// next try waits half of `start_timeout`). Returns the generation it had.
    pub(super) fn drop_successor(&mut self, k: usize, why: Option<&str>) -> Option<u64> {
        let succ = self.workers[k].successor.take()?;
        let mut child = succ.child;
        let _ = child.kill();
        let _ = child.wait();
        let _ = fs::remove_file(successor_marker(&self.id, k, succ.generation));
        let _ = fs::remove_file(successor_go(&self.id, k, succ.generation));
        if let Some(why) = why {
            let tail = fs::read_to_string(&succ.stderr_path).unwrap_or_default();
            let tail = tail.trim_end();
            self.counts[k].last_failure = Some(format!(
                "the successor of worker {k} {why}; the worker serves on{}",
                if tail.is_empty() {
                    String::new()
                } else {
                    format!(": {}", &tail[tail.len().saturating_sub(500)..])
                }
            ));
            self.workers[k].recycle_pause = Some(Instant::now() + self.cfg.start_timeout / 2);
        }
        let _ = fs::remove_file(&succ.stderr_path);
        Some(succ.generation)
    }

    /// Close worker `k` (idle) and let its successor take over its ports and envs.
    fn hand_over(&mut self, k: usize) -> Result<(), PoolError> {
        let Some(succ) = self.workers[k].successor.take() else {
            return Ok(());
        };
        let s = &mut self.workers[k];
        if s.child.is_some() {
            s.seq += 1;
            let close = Command::new(Op::Close, 0).encode();
            let _ = s.ports.send_cmd(s.seq, close, 0, |_| {});
        }
        if let Some(old) = s.child.take() {
            reap(old, CLOSE_WITHIN);
        }
        if let Some(stats) = &self.stats {
            stats.new_process(k); // the successor: none of its answers taken, no command read
        }
        self.workers[k].sent_before = self.workers[k].ports.sent();
        rogue_gym_ipc::cleanup_dead_nodes(&self.id)?;
        rogue_gym_ipc::private::create_private_file(&successor_go(&self.id, k, succ.generation))?;
        let s = &mut self.workers[k];
        while s.ports.try_recv()?.is_some() {}
        self.arrived.retain(|&w| w != k);
        let _ = fs::remove_file(&s.stderr_path);
        let _ = fs::remove_file(successor_marker(&self.id, k, succ.generation));
        s.generation = succ.generation;
        s.pid = succ.child.id();
        s.child = Some(succ.child);
        s.stderr_path = succ.stderr_path;
        s.starting_now(false);
        s.cut = true;
        s.recycled = true;
        s.served = 0;
        s.rss_read = None;
        s.rss = 0;
        s.rss_growth = 0;
        self.pids[k].store(s.pid, std::sync::atomic::Ordering::Relaxed);
        self.counts[k].recycles += 1;
        Ok(())
    }
}
