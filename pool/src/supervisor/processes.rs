//! The worker processes: starting one (its stderr to a private file, the pool's buffers
//! handed over by descriptor), and replacing a lost one with its next generation.

use std::fs;
use std::ops::Range;
use std::path::PathBuf;
use std::process::{Child, Stdio};

use super::Supervisor;
use crate::error::PoolError;

impl Supervisor {
    /// The envs worker `k` hosts.
    pub(super) fn env_range(&self, k: usize) -> Range<usize> {
        self.blocks[k].clone()
    }

    /// Start the process of worker `k`, generation `generation` (`successor`: a planned
    /// replacement, see `recycling`), its stderr going to a private file.
    pub(super) fn start_process(
        &self,
        k: usize,
        generation: u64,
        successor: bool,
    ) -> Result<(Child, PathBuf), PoolError> {
        let log = self.id.aux_dir().join(format!("w{k}.g{generation}.stderr"));
        let file = rogue_gym_ipc::private::create_private_file(&log)?;
        let w = &self.cfg.worker;
        let fds = self.shared_fds()?;
        let mut command = std::process::Command::new(&w.program);
        command
            .args(&w.args)
            .arg("--config")
            .arg(&self.config_path)
            .args(["--index", &k.to_string()])
            .args(["--generation", &generation.to_string()])
            .args(["--ppid", &std::process::id().to_string()])
            .args(["--shared-fds", &fds.map(|f| f.to_string()).join(",")]);
        // The pool's buffers reach this worker alone: kept open across its exec only.
        // SAFETY: the closure makes async-signal-safe calls only (`fcntl`).
        unsafe {
            std::os::unix::process::CommandExt::pre_exec(&mut command, move || {
                rogue_gym_ipc::buffer::inheritable(&fds)
            });
        }
        if successor {
            command.arg("--successor");
        }
        let child = command
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(file)
            .spawn()
            .map_err(|e| PoolError::StartFailed {
                worker: k,
                reason: format!(
                    "cannot execute {} {:?}: {e}; check the worker command (program and leading args)",
                    w.program.display(),
                    w.args
                ),
                stderr_tail: String::new(),
            })?;
        Ok((child, log))
    }

    /// The descriptors of the pool's buffers, in [`crate::wire::SHARED_FDS`] order.
    fn shared_fds(&self) -> Result<[std::os::fd::RawFd; 3], PoolError> {
        let fd = |b: Option<&rogue_gym_ipc::SharedBuffer>| {
            b.and_then(|b| b.raw_fd()).ok_or(PoolError::Closed)
        };
        Ok([
            fd(self.batch.as_deref())?,
            fd(self.books.as_ref().map(|b| b.buffer()))?,
            fd(self.stats.as_ref().map(|s| s.buffer()))?,
        ])
    }

    pub(super) fn spawn(&mut self, k: usize, then_reset: bool) -> Result<(), PoolError> {
        if let Some(stats) = &self.stats {
            stats.new_process(k); // a new process: none of its answers taken
        }
        let (child, log) = self.start_process(k, self.workers[k].generation, false)?;
        self.pids[k].store(child.id(), std::sync::atomic::Ordering::Relaxed);
        let s = &mut self.workers[k];
        s.pid = child.id();
        s.child = Some(child);
        s.stderr_path = log;
        s.served = 0;
        s.sent_before = s.ports.sent();
        s.partial = false;
        s.rss_read = None;
        s.rss = 0;
        s.rss_growth = 0;
        s.starting_now(then_reset);
        Ok(())
    }

    /// Forget worker `k`'s incarnation (its iceoryx2 leftovers and queued answers) and spawn the
    /// next generation.
    pub(super) fn respawn_now(&mut self, k: usize, then_reset: bool) -> Result<(), PoolError> {
        rogue_gym_ipc::cleanup_dead_nodes(&self.id)?;
        // Drop whatever the dead incarnation left in the queue.
        while self.workers[k].ports.try_recv()?.is_some() {}
        self.arrived.retain(|&w| w != k);
        // Its stderr's tail is in the failure report already: a storm must not pile up files.
        let _ = fs::remove_file(&self.workers[k].stderr_path);
        // A successor being built (recycling) is of no use now: the next generation is after it.
        if let Some(g) = self.drop_successor(k, None) {
            self.workers[k].generation = g;
        }
        self.workers[k].recycled = false;
        self.workers[k].generation += 1;
        self.spawn(k, then_reset)
    }
}
