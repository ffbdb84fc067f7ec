//! The worker processes seen from the supervisor: spawning, commands, receiving blocks, and
//! detecting and handling dead or hung workers.

use std::fs;
use std::io::{Read, Seek, SeekFrom};
use std::ops::Range;
use std::os::unix::process::ExitStatusExt;
use std::path::PathBuf;
use std::process::{Child, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use rogue_gym_ipc::{BlockSample, SupervisorPorts};

use super::actions::Actions;
use super::{Supervisor, slot_answers};
use crate::batch::Block;
use crate::config::FailurePolicy;
use crate::error::{FailureCause, PoolError, WorkerFailure};
use crate::wire::answer::{ANSWER_WORDS, Answer, BlockKind, rows_of};
use crate::wire::books::next_episode;
use crate::wire::command::next_seq;
use crate::wire::{Command, EnvFault, KEEP_EPISODE, Op, calls, env_fault_path, env_fault_path_of};

pub(super) enum LinkState {
    /// Dead, waiting out its restart backoff; respawned at `until` (restart policy).
    Down { until: Instant, then_reset: bool },
    /// Process started, waiting for its READY block.
    Starting { since: Instant, then_reset: bool },
    /// Nothing outstanding.
    Idle,
    /// A command is outstanding.
    Pending { since: Instant },
    /// Its answer has arrived and waits to be handed out.
    Ready(BlockSample),
}

impl LinkState {
    /// Lost and not back yet: waiting out its backoff, or starting.
    pub(super) fn coming_back(&self) -> bool {
        matches!(self, LinkState::Down { .. } | LinkState::Starting { .. })
    }
}

pub(super) struct WorkerLink {
    pub(super) ports: SupervisorPorts,
    pub(super) child: Option<Child>,
    pub(super) pid: u32,
    pub(super) generation: u64,
    pub(super) seq: u64,
    pub(super) state: LinkState,
    pub(super) restarted: bool,
    /// It died while idle and was replaced (restart policy): its envs' episodes were cut, so
    /// its next command resets them (and they report `restarted`).
    pub(super) cut: bool,
    pub(super) stderr_path: PathBuf,
    /// Observation target of the last command (see [`Command::target`]).
    pub(super) target: u32,
    /// Failures of this worker in a row, with no answer to a command in between (see
    /// [`restart_backoff`]); an answer ends the streak.
    pub(super) restart_streak: u32,
    /// The command whose answer it gave last: the copy of the episode books to read
    /// ([`crate::wire::books`]).
    pub(super) delivered: Option<u64>,
    /// Its envs start from episode 0 at the next reset (a new pool, or a new seed schedule).
    pub(super) first_episodes: bool,
    /// Action extras staged for its next step ([`crate::Pool::stage_action_extras`]), encoded
    /// as a call file.
    pub(super) action_extras: Option<Vec<u8>>,
    /// Env steps served since this incarnation started (for `recycle_after_steps`).
    pub(super) served: u64,
    /// Commands sent through its ports before its current process started (those it read
    /// are counted from then: `StatsBuffer::read`).
    pub(super) sent_before: u64,
    /// Its successor while it builds its envs (see `recycling`).
    pub(super) successor: Option<super::recycling::Successor>,
    /// It was replaced by plan: the envs of its next block report `worker_recycled`.
    pub(super) recycled: bool,
    /// When its resident memory was last read, and what it was (bytes).
    pub(super) rss_read: Option<Instant>,
    pub(super) rss: u64,
    /// How much it grew between the last two readings.
    pub(super) rss_growth: u64,
    /// No successor is started before this (one failed).
    pub(super) recycle_pause: Option<Instant>,
    /// Its envs run on threads, and some are in flight under partial commands
    /// ([`Command::partial`]): it answers them one by one, and takes more commands meanwhile.
    pub(super) partial: bool,
}

impl WorkerLink {
    /// The link to a worker not started yet, over its `ports`.
    pub(super) fn new(ports: SupervisorPorts) -> Self {
        WorkerLink {
            ports,
            child: None,
            pid: 0,
            generation: 0,
            seq: 0,
            state: LinkState::Idle,
            restarted: false,
            served: 0,
            sent_before: 0,
            successor: None,
            recycled: false,
            rss_read: None,
            rss: 0,
            rss_growth: 0,
            recycle_pause: None,
            partial: false,
            cut: false,
            restart_streak: 0,
            delivered: None,
            first_episodes: true,
            stderr_path: PathBuf::new(),
            target: 0,
            action_extras: None,
        }
    }
}

/// The longest wait before a restart.
const MAX_BACKOFF: Duration = Duration::from_secs(2);

/// How long to wait before restarting a worker that failed `streak` times in a row without
/// answering a command in between: nothing for the first, then 50 ms, doubling up to
/// [`MAX_BACKOFF`] or half of `start_timeout`, whichever is less (a lost worker has
/// `start_timeout` to come back: the backoff leaves it half for its start-up and reset), so a
/// worker that cannot come up (a bad env, a full disk) cannot spin the machine before the
/// restart budget ends it. Each worker has its own streak and waits out its own backoff while
/// the others run and restart.
pub(super) fn restart_backoff(streak: u32, start_timeout: Duration) -> Duration {
    match streak {
        0 => Duration::ZERO,
        n => Duration::from_millis(50)
            .saturating_mul(1 << (n - 1).min(16))
            .min(MAX_BACKOFF)
            .min(start_timeout / 2),
    }
}

fn stderr_tail(path: &PathBuf) -> String {
    const N: u64 = 2048;
    let Ok(mut f) = fs::File::open(path) else {
        return String::new();
    };
    let len = f.metadata().map(|m| m.len()).unwrap_or(0);
    let _ = f.seek(SeekFrom::Start(len.saturating_sub(N)));
    let mut buf = Vec::new();
    let _ = f.read_to_end(&mut buf);
    String::from_utf8_lossy(&buf).into_owned()
}

fn status_parts(st: &ExitStatus) -> (Option<i32>, Option<i32>) {
    (st.code(), st.signal())
}

impl Supervisor {
    pub(super) fn env_range(&self, k: usize) -> Range<usize> {
        self.blocks[k].clone()
    }

    /// A command to the workers, paced as the machine's booking says (`machine.rs`).
    fn command(&mut self, op: Op, target: u32) -> Command {
        Command {
            pace: self.machine.worker_pace(self.async_api.on),
            ..Command::new(op, target)
        }
    }

    /// Write the action extras staged for worker `k`'s next step to its file; whether there
    /// were any ([`Command::action_extras`]).
    fn write_action_extras(&mut self, k: usize) -> Result<bool, PoolError> {
        let Some(extras) = self.workers[k].action_extras.take() else {
            return Ok(false);
        };
        let path = calls::action_extras_path(&self.id, k, self.workers[k].generation);
        calls::write(&path, &extras).map_err(PoolError::Io)?;
        Ok(true)
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
        s.state = LinkState::Starting {
            since: Instant::now(),
            then_reset,
        };
        Ok(())
    }

    /// Reset command to worker `k`; with `mask` (the whole pool's), envs whose entry is false
    /// get [`KEEP_EPISODE`] (keep state, re-write the current observation).
    pub(super) fn send_reset(
        &mut self,
        k: usize,
        target: u32,
        mask: Option<&[bool]>,
    ) -> Result<(), PoolError> {
        let range = self.env_range(k);
        self.workers[k].action_extras = None; // staged for a step that a reset replaces
        self.workers[k].target = target;
        // A replaced worker resets all its envs; in a partial reset they say why.
        let cut = std::mem::take(&mut self.workers[k].cut);
        self.workers[k].restarted |= cut && mask.is_some();
        let mask = mask.filter(|_| !cut);
        let mut eps = Vec::with_capacity(range.len());
        for i in range {
            if mask.is_some_and(|m| !m[i]) {
                eps.push(KEEP_EPISODE);
                continue;
            }
            let Some((e, _)) = self.book(k, i) else {
                eps.push(0);
                continue;
            };
            let Some(next) = next_episode(e) else {
                // The worker wrote an episode index no env reaches: its envs' place in the
                // seed schedule is lost, so they start over from episode 0.
                self.workers[k].first_episodes = true;
                let what = format!("env {i}'s episode index {e} in the episode books");
                return self.lose(k, FailureCause::Corrupt(what), true);
            };
            eps.push(next);
        }
        let cmd = Command {
            reload_seeds: std::mem::take(&mut self.reload_seeds[k]),
            ..self.command(Op::Reset, target)
        };
        let s = &mut self.workers[k];
        s.seq = next_seq(s.seq, s.delivered);
        s.target = target;
        s.ports
            .send_cmd(s.seq, cmd.encode(), eps.len(), |p| p.copy_from_slice(&eps))?;
        s.state = LinkState::Pending {
            since: Instant::now(),
        };
        Ok(())
    }

    /// Step command to worker `k`; `actions` holds exactly its block's actions. A replaced
    /// worker ([`WorkerLink::cut`]) resets its envs instead, which report `restarted`.
    pub(super) fn send_step(
        &mut self,
        k: usize,
        actions: Actions<'_>,
        target: u32,
    ) -> Result<(), PoolError> {
        if self.workers[k].cut {
            self.workers[k].restarted = true;
            return self.send_reset(k, target, None);
        }
        let aw = self.spec.action_words();
        let cmd = Command {
            action_extras: self.write_action_extras(k)?,
            ..self.command(Op::Step, target)
        };
        let s = &mut self.workers[k];
        s.seq = next_seq(s.seq, s.delivered);
        s.target = target;
        s.served += self.blocks[k].len() as u64;
        let words = self.blocks[k].len() * aw;
        s.ports
            .send_cmd(s.seq, cmd.encode(), words, |p| match actions {
                Actions::Indices(a) => {
                    for (d, a) in p.iter_mut().zip(a) {
                        *d = *a as u64;
                    }
                }
                Actions::Bytes(b) => {
                    let ab = self.spec.action_bytes;
                    for (j, w) in p.chunks_mut(aw).enumerate() {
                        w.fill(0);
                        rogue_gym_ipc::words_as_bytes_mut(w)[..ab]
                            .copy_from_slice(&b[j * ab..(j + 1) * ab]);
                    }
                }
            })?;
        s.state = LinkState::Pending {
            since: Instant::now(),
        };
        Ok(())
    }

    /// Step command to worker `k` from action words (`aw` per env of its block); with `only`
    /// (one word per env, 0 = left alone), a [`Command::subset`] step of the envs it names; answered
    /// into batch slot `target - 1` in place, or by block (`target` 0). A replaced
    /// worker ([`WorkerLink::cut`]) resets all its envs instead, which report `restarted`.
    pub(super) fn send_words(
        &mut self,
        k: usize,
        words: &[u64],
        only: Option<&[u64]>,
        target: u32,
        partial: bool,
    ) -> Result<(), PoolError> {
        if self.workers[k].cut {
            self.workers[k].restarted = true;
            return self.send_reset(k, 0, None);
        }
        let served = only.map_or(self.blocks[k].len(), |o| {
            o.iter().filter(|&&w| w != 0).count()
        });
        let only = only.unwrap_or(&[]);
        let cmd = Command {
            action_extras: self.write_action_extras(k)?,
            subset: !only.is_empty(),
            partial,
            ..self.command(Op::Step, target)
        };
        let s = &mut self.workers[k];
        s.seq = next_seq(s.seq, s.delivered);
        s.target = target;
        s.served += served as u64;
        s.ports
            .send_cmd(s.seq, cmd.encode(), words.len() + only.len(), |p| {
                let (a, o) = p.split_at_mut(words.len());
                a.copy_from_slice(words);
                o.copy_from_slice(only);
            })?;
        if !(partial && s.partial) {
            // A worker already answering partial commands stays pending since its oldest.
            s.state = LinkState::Pending {
                since: Instant::now(),
            };
        }
        s.partial |= partial;
        Ok(())
    }

    /// Worker `k`'s answer by block, which has arrived (it is idle again); `None` when the
    /// answer failed a check and the worker was handled as failed ([`Supervisor::lose`]).
    pub(super) fn take_block(&mut self, k: usize) -> Result<Option<Block>, PoolError> {
        let sample = self.take_answer(k)?;
        let s = &mut self.workers[k];
        let restarted = std::mem::take(&mut s.restarted);
        if std::mem::take(&mut s.recycled) && restarted {
            self.recycling.replaced_envs.extend(self.blocks[k].clone());
        }
        let layout = self.layouts[k];
        let seq = sample.user_header().seq;
        let first = self.blocks[k].start;
        let any_apart = (0..layout.envs).any(|j| layout.record(sample.payload(), j).extra_apart());
        let apart = if any_apart {
            match self.take_apart(k, seq) {
                Ok(apart) => apart,
                Err(what) => {
                    drop(sample);
                    self.lose_corrupt(k, what)?;
                    return Ok(None);
                }
            }
        } else {
            Vec::new()
        };
        Ok(Some(Block {
            worker: k,
            env_start: first,
            layout,
            restarted,
            sample,
            apart: apart
                .into_iter()
                .map(|(e, b)| ((e - first) as u32, b))
                .collect(),
        }))
    }

    /// Take every available block of starting and pending workers.
    pub(super) fn poll_all(&mut self) -> Result<(), PoolError> {
        for k in 0..self.workers.len() {
            loop {
                let s = &mut self.workers[k];
                if !matches!(
                    s.state,
                    LinkState::Starting { .. } | LinkState::Pending { .. }
                ) {
                    break;
                }
                let Some(sample) = s.ports.try_recv()? else {
                    break;
                };
                let h = *sample.user_header();
                if h.generation != s.generation {
                    continue; // from a dead incarnation
                }
                if let Some(stats) = &self.stats {
                    stats.took(k); // the worker may answer again (see `worker/concurrent.rs`)
                }
                if s.partial && matches!(s.state, LinkState::Pending { .. }) {
                    match BlockKind::from_word(h.kind) {
                        Some(BlockKind::Rows) => self.take_rows(k, &sample)?,
                        Some(BlockKind::Error) => self.take_row_fault(k, &sample)?,
                        _ => {} // stale: nothing else answers a partial command
                    }
                    continue;
                }
                match (&s.state, BlockKind::from_word(h.kind)) {
                    (LinkState::Starting { then_reset, .. }, Some(BlockKind::Ready)) => {
                        if *then_reset {
                            drop(sample);
                            // Same observation target as the interrupted command; in the
                            // async API by block (the reset covers envs the caller holds).
                            let target = if self.async_api.on { 0 } else { s.target };
                            self.send_reset(k, target, None)?;
                        } else {
                            s.state = LinkState::Idle;
                        }
                    }
                    (LinkState::Pending { .. }, Some(BlockKind::Data)) if h.seq == s.seq => {
                        s.restart_streak = 0;
                        // The worker wrote its envs' books for this answer.
                        s.delivered = Some(h.seq);
                        s.first_episodes = false;
                        s.state = LinkState::Ready(sample);
                        self.arrived.push_back(k);
                    }
                    (LinkState::Pending { .. }, Some(BlockKind::Call)) if h.seq == s.seq => {
                        s.restart_streak = 0;
                        s.state = LinkState::Idle;
                    }
                    (LinkState::Pending { .. }, Some(BlockKind::Error)) if h.seq == s.seq => {
                        drop(sample);
                        s.restart_streak = 0;
                        s.state = LinkState::Idle;
                        let path = env_fault_path(&self.id, k, s.generation);
                        let fault = EnvFault::take(&path).unwrap_or_else(|e| {
                            EnvFault::new(
                                self.blocks[k].start as u64,
                                "a command",
                                format!("an env of the worker failed; {e}"),
                            )
                        });
                        self.failures.must_reset = true;
                        self.call.faults.push(PoolError::EnvFailed {
                            fault: Box::new(fault),
                            worker: k,
                            pid: s.pid,
                        });
                    }
                    _ => {} // stale answer: drop it
                }
            }
        }
        Ok(())
    }

    /// Worker `k`'s answer for envs of its partial commands, done one by one (its envs run on
    /// threads): they are ready, their rows in their slots, checked as any answer in place;
    /// a bad answer is the worker's failure.
    fn take_rows(&mut self, k: usize, sample: &BlockSample) -> Result<(), PoolError> {
        let (words, n) = slot_answers::answer_words(sample);
        let block = self.blocks[k].clone();
        let checked = rows_of(sample.payload(), ANSWER_WORDS, block.len()).and_then(|rows| {
            let a = Answer::decode(&words, self.slot_layout.extra_bytes)?;
            Ok((rows, a))
        });
        let (rows, answer) = match checked {
            Ok(v) => v,
            Err(what) => return self.lose_corrupt(k, format!("its answer {n}: {what}")),
        };
        let envs: Vec<usize> = rows.iter().map(|&j| block.start + j).collect();
        for &e in &envs {
            let Some(slot) = self.async_api.envs.partial_slot(e) else {
                continue;
            };
            let rows = self.rows_of(slot)?;
            if let Err(what) = self.check_flags(&rows, e..e + 1) {
                return self.lose_corrupt(k, format!("its answer {n}: {what}"));
            }
        }
        let apart = if answer.apart {
            match self.take_apart(k, n) {
                Ok(a) => a,
                Err(what) => return self.lose_corrupt(k, what),
            }
        } else {
            Vec::new()
        };
        if let Err(what) = self.async_api.envs.arrive_rows(k, &envs, apart) {
            return self.lose_corrupt(k, format!("its answer {n}: {what}"));
        }
        self.workers[k].restart_streak = 0;
        self.settle_partial(k);
        Ok(())
    }

    /// Worker `k`'s report of an env of a partial command that failed: raised with the call's
    /// other failures (the caller resets), the env no longer in flight.
    fn take_row_fault(&mut self, k: usize, sample: &BlockSample) -> Result<(), PoolError> {
        let n = sample.user_header().seq;
        let block = self.blocks[k].clone();
        let rows = match rows_of(sample.payload(), 0, block.len()) {
            Ok(rows) if rows.len() == 1 => rows,
            Ok(rows) => {
                return self.lose_corrupt(k, format!("an error answer naming {} envs", rows.len()));
            }
            Err(what) => return self.lose_corrupt(k, format!("its error answer {n}: {what}")),
        };
        let e = block.start + rows[0];
        let path = env_fault_path_of(&self.id, k, self.workers[k].generation, n);
        let fault = EnvFault::take(&path).unwrap_or_else(|why| {
            EnvFault::new(e as u64, "a command", format!("the env failed; {why}"))
        });
        self.async_api.envs.fail_row(k, e);
        self.failures.must_reset = true;
        self.call.faults.push(PoolError::EnvFailed {
            fault: Box::new(fault),
            worker: k,
            pid: self.workers[k].pid,
        });
        self.settle_partial(k);
        Ok(())
    }

    /// After an answer of worker `k`'s partial commands: idle once none of its envs is in
    /// flight, else pending since its oldest env in flight was sent (what `step_timeout`
    /// bounds).
    fn settle_partial(&mut self, k: usize) {
        let s = &mut self.workers[k];
        match self.async_api.envs.oldest_partial(k) {
            Some(since) if !self.async_api.envs.sent_to(k).is_empty() => {
                s.state = LinkState::Pending { since };
            }
            _ if self.async_api.envs.sent_to(k).is_empty() => {
                s.partial = false;
                s.state = LinkState::Idle;
            }
            _ => {}
        }
    }

    /// Detect dead and hung workers, whatever they were doing (starting, restarting, or
    /// answering a command), and handle each per policy ([`Supervisor::handle_failure`]). A failure
    /// the caller must hear of is queued in `self.faults`; only a spent restart budget, and a
    /// SIGBUS during the pool's first start, return at once.
    pub(super) fn check_liveness(&mut self) -> Result<(), PoolError> {
        for k in 0..self.workers.len() {
            let range = self.env_range(k);
            let s = &mut self.workers[k];
            if let LinkState::Down { until, then_reset } = s.state {
                if Instant::now() >= until {
                    self.respawn_now(k, then_reset)?;
                }
                continue;
            }
            let (since, starting, then_reset) = match s.state {
                LinkState::Starting { since, then_reset } => (since, true, then_reset),
                LinkState::Pending { since } => (since, false, true),
                // Restart policy: an idle worker that died is replaced now, not at its next
                // command, so that it comes back while others are waited for.
                LinkState::Idle if self.cfg.on_worker_failure == FailurePolicy::Restart => {
                    (Instant::now(), false, false)
                }
                _ => continue,
            };
            let idle = matches!(s.state, LinkState::Idle);
            let exited = match s.child.as_mut() {
                Some(ch) => ch.try_wait().ok().flatten(),
                None => None,
            };
            let limit = if starting {
                Some(self.cfg.start_timeout)
            } else {
                self.cfg.step_timeout
            };
            let lost = s.child.is_none();
            let hung = !lost && exited.is_none() && limit.is_some_and(|l| since.elapsed() > l);
            if (idle && exited.is_none()) || (!lost && exited.is_none() && !hung) {
                continue;
            }
            s.cut |= idle;
            if hung && let Some(ch) = s.child.as_mut() {
                let _ = ch.kill();
            }
            let status = match (exited, s.child.as_mut()) {
                (Some(st), _) => Some(st),
                (None, Some(ch)) => ch.wait().ok(),
                (None, None) => None,
            };
            s.child = None;
            let (code, signal) = status.as_ref().map(status_parts).unwrap_or((None, None));
            let tail = stderr_tail(&s.stderr_path);
            let fault_path = env_fault_path(&self.id, k, s.generation);
            if starting && fault_path.exists() {
                // An env that failed to build: its report goes to the caller as is. The worker
                // is respawned (not counted as a crash) so that a reset can try again.
                let fault = EnvFault::take(&fault_path).map_err(PoolError::Io)?;
                let pid = s.pid;
                self.respawn_now(k, then_reset)?;
                self.failures.must_reset = true;
                self.call.faults.push(PoolError::EnvFailed {
                    fault: Box::new(fault),
                    worker: k,
                    pid,
                });
                continue;
            }
            if starting && !self.started && !hung && signal.is_none() {
                // The pool's first start, and the worker gave up by itself (bad arguments, a
                // config it cannot read, no such program): another try would fail the same way.
                let reason = match code {
                    Some(c) => format!("exited with code {c} during start-up"),
                    None => "exited during start-up".into(),
                };
                return Err(PoolError::StartFailed {
                    worker: k,
                    reason,
                    stderr_tail: tail,
                });
            }
            let sigbus = signal == Some(nix::libc::SIGBUS);
            let failure = WorkerFailure {
                worker: k,
                env_ids: range.clone(),
                pid: s.pid,
                cause: match (hung, starting) {
                    (true, true) => FailureCause::NotReady(self.cfg.start_timeout),
                    (true, false) => FailureCause::Hung(limit.unwrap_or_default()),
                    _ => FailureCause::Died,
                },
                exit_code: code,
                signal,
                seeds: range
                    .clone()
                    .map(|i| self.book(k, i).map_or(0, |(_, seed)| seed))
                    .collect(),
                stderr_tail: tail,
                starting,
            };
            if sigbus {
                // A page of shared memory the filesystem could not give: restarting would only
                // die again. Fail the call (the pool's first start: the constructor) with the
                // numbers; a later reset() tries once more.
                let err = self.out_of_shared_memory(k, failure)?;
                if !self.started {
                    return Err(err);
                }
                self.call.faults.push(err);
                continue;
            }
            self.handle_failure(k, failure, then_reset)?;
        }
        Ok(())
    }

    /// Worker `k` was killed by SIGBUS: probably /dev/shm is full. Respawned once, not in a
    /// loop; the call is to fail with the [`PoolError::OutOfSharedMemory`] returned.
    fn out_of_shared_memory(
        &mut self,
        k: usize,
        failure: WorkerFailure,
    ) -> Result<PoolError, PoolError> {
        self.failures.deaths += 1;
        self.counts[k].restarts += 1;
        self.counts[k].last_failure = Some(failure.to_string());
        self.failures.must_reset = true;
        let err = PoolError::OutOfSharedMemory {
            failure: Box::new(failure),
            need: self.shm_need,
            room: rogue_gym_ipc::shm_room().ok(),
        };
        if self.started {
            self.respawn_now(k, false)?;
        }
        Ok(err)
    }

    /// Forget worker `k`'s incarnation (its iceoryx2 leftovers and queued answers) and spawn the
    /// next generation.
    fn respawn_now(&mut self, k: usize, then_reset: bool) -> Result<(), PoolError> {
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

    /// Worker `k` failed for `cause`, found by a check of what it wrote rather than by its
    /// exit: kill it and handle the failure like a death ([`Supervisor::handle_failure`]).
    pub(super) fn lose(
        &mut self,
        k: usize,
        cause: FailureCause,
        then_reset: bool,
    ) -> Result<(), PoolError> {
        let range = self.env_range(k);
        let s = &mut self.workers[k];
        let status = s.child.take().and_then(|mut ch| {
            let _ = ch.kill();
            ch.wait().ok()
        });
        let (code, signal) = status.as_ref().map(status_parts).unwrap_or((None, None));
        s.state = LinkState::Idle;
        let failure = WorkerFailure {
            worker: k,
            env_ids: range.clone(),
            pid: s.pid,
            cause,
            exit_code: code,
            signal,
            seeds: range
                .map(|i| self.book(k, i).map_or(0, |(_, seed)| seed))
                .collect(),
            stderr_tail: stderr_tail(&self.workers[k].stderr_path),
            starting: false,
        };
        self.handle_failure(k, failure, then_reset)
    }

    /// A worker died or hung (while starting, restarting or stepping). Restart policy: count it
    /// against the budget and respawn it once its own backoff has passed (at once for a first
    /// failure; meanwhile it is [`LinkState::Down`] and the other workers go on); its envs, if
    /// an episode was cut (`then_reset`), restart theirs and are flagged. Raise policy: respawn
    /// it and queue [`PoolError::WorkerFailed`]. Either way the pool steps again after one
    /// reset.
    pub(super) fn handle_failure(
        &mut self,
        k: usize,
        failure: WorkerFailure,
        then_reset: bool,
    ) -> Result<(), PoolError> {
        self.failures.deaths += 1;
        self.call.failed_at.get_or_insert_with(Instant::now);
        let counts = &mut self.counts[k];
        counts.restarts += 1;
        counts.timeouts += u64::from(matches!(failure.cause, FailureCause::Hung(_)));
        counts.last_failure = Some(failure.to_string());
        match self.cfg.on_worker_failure {
            FailurePolicy::Raise => {
                self.failures.last_failure = Some(Box::new(failure.clone()));
                self.respawn_now(k, false)?;
                self.failures.must_reset = true;
                self.call
                    .faults
                    .push(PoolError::WorkerFailed(Box::new(failure)));
                Ok(())
            }
            FailurePolicy::Restart => {
                self.failures.restarts += 1;
                if self.failures.restarts > self.cfg.max_restarts {
                    self.failures.must_reset = true;
                    return Err(PoolError::RestartBudgetExceeded {
                        max_restarts: self.cfg.max_restarts,
                        last: Box::new(failure),
                    });
                }
                self.failures.last_failure = Some(Box::new(failure));
                let s = &mut self.workers[k];
                let backoff = restart_backoff(s.restart_streak, self.cfg.start_timeout);
                s.restart_streak = s.restart_streak.saturating_add(1);
                s.restarted |= then_reset;
                if backoff.is_zero() {
                    self.respawn_now(k, then_reset)
                } else {
                    s.state = LinkState::Down {
                        until: Instant::now() + backoff,
                        then_reset,
                    };
                    Ok(())
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn restart_backoff_doubles_from_nothing_up_to_its_cap() {
        let start = Duration::from_secs(30);
        let ms = |n| restart_backoff(n, start).as_millis();
        assert_eq!([ms(0), ms(1), ms(2), ms(3), ms(6)], [0, 50, 100, 200, 1600]);
        assert_eq!(restart_backoff(7, start), MAX_BACKOFF);
        assert_eq!(restart_backoff(u32::MAX, start), MAX_BACKOFF);
    }

    #[test]
    fn restart_backoff_leaves_half_the_start_timeout_for_the_start() {
        let start = Duration::from_millis(600);
        assert_eq!(restart_backoff(3, start), Duration::from_millis(200));
        assert_eq!(restart_backoff(4, start), Duration::from_millis(300));
        assert_eq!(restart_backoff(20, start), Duration::from_millis(300));
    }
}
