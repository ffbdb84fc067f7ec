//! The executor with env threads (`WorkerConfig::env_threads` > 0): for envs that wait (a
//! socket, a remote simulator, a subprocess, a sleep), so that an env that waits holds its own
//! thread only, not its worker-mates. The loop is the executor's (`executor.rs`); this file
//! starts the threads, hands them a command's jobs and takes back the finished envs.
//!
//! Two kinds of thread:
//!
//! * **env threads** (`env_threads` of them, `env_threads.rs`) take jobs, one env's reset or
//!   step each, from one queue; the env writes its observation, final observation and extra
//!   info straight into its own rows of the batch slot the command names for it, as an env
//!   served inline does; each env is behind a lock, taken by one thread at a time. A job done goes to
//!   the done list, and its thread wakes the worker's command listener ([`CmdWaker`]);
//! * the worker's **own thread** waits on that one listener for both commands and finished
//!   envs, takes commands from the port, starts them (in order: a command waits until every
//!   env it names is idle), writes each finished env's record and episode books, and publishes
//!   the answers: one per command, when all its envs are done; or, for a `partial` command (the
//!   async API's steps), envs as they finish ([`BlockKind::Rows`]), several to an
//!   answer when they finish together, while further commands for other envs arrive.
//!
//! One listener for both keeps a step's round trip inside the worker to three wake-ups (the
//! worker's thread, the env thread, the worker's thread): each costs tens of microseconds
//! where it crosses cores on a VM (`handoff_us` in `benchmarks/async_pools.py`), beside a
//! millisecond that an env waits.
//!
//! Flow control: the supervisor takes answers only inside the caller's calls. The answer port
//! holds four; a worker holds its finished envs while three answers are untaken (the count of
//! answers taken is in shared memory, `StatsBuffer::taken`), and checks again every
//! millisecond, folding whatever finishes meanwhile into its next answer. Nothing is dropped,
//! and nothing spins.
//!
//! What holds as inline: each env's trajectory (its state is its own), an env
//! that fails fails alone (an error answer names it; the others go on), and a worker that dies
//! costs its envs one restarted episode. What differs: a command's envs finish in any order,
//! and streaming stores are off (each thread writes its env's rows).

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, PoisonError, RwLock};

use rogue_gym_ipc::CmdWaker;

use super::env_threads::{Area, Ctx, Done, Job, Shared, batch_scheduling, env_thread, guard};
use super::envs::{WorkerEnvs, lock};
use super::{Incoming, Worker, WorkerError};
use crate::stats::Counter;
use crate::wire::answer::{AnswerBuilder, BlockKind};
use crate::wire::{EnvFault, Serve, env_fault_path_of};

/// Answers a worker may have untaken before it holds its finished envs (the answer port
/// holds four; one is left for an answer that cannot wait, an error's).
const UNTAKEN: u64 = 3;

/// A command started and not yet answered whole.
pub(super) struct Running {
    pub(super) seq: u64,
    /// The slot (`s + 1`) each env of the block writes in (0: not one of the command's).
    pub(super) targets: Vec<u64>,
    partial: bool,
    /// Its envs not done yet.
    pub(super) remaining: usize,
    answer: AnswerBuilder,
    apart: Vec<(u32, Vec<u8>)>,
    /// The first env that failed.
    fault: Option<EnvFault>,
}

/// Finished envs of partial commands, for the next answer.
#[derive(Default)]
pub(super) struct Finished {
    pub(super) rows: Vec<u64>,
    answer: AnswerBuilder,
    apart: Vec<(u32, Vec<u8>)>,
    /// Envs that failed, with their fault: an error answer each.
    pub(super) failed: Vec<(usize, EnvFault)>,
}

/// Stop the env threads (those stuck in an env's wait are not joined: the process exits with
/// them).
pub(super) fn stop_env_threads(shared: &Shared) {
    shared.stop.store(true, Ordering::Relaxed);
    shared.job_ready.notify_all();
    drop(
        (shared.waker.write())
            .unwrap_or_else(PoisonError::into_inner)
            .take(),
    );
}

impl Worker<'_> {
    /// Start the env threads of a worker whose envs run on threads (`None`: its envs run
    /// inline).
    pub(super) fn start_env_threads(&mut self) -> Result<Option<Arc<Shared>>, WorkerError> {
        let WorkerEnvs::Shared(envs) = &self.envs else {
            return Ok(None);
        };
        let waker = CmdWaker::new(&self.node, self.args.index)?;
        let shared = Arc::new(Shared {
            envs: envs.clone(),
            jobs: Mutex::new(VecDeque::new()),
            job_ready: Condvar::new(),
            done: Mutex::new(Vec::new()),
            waker: RwLock::new(Some(waker)),
            stop: AtomicBool::new(false),
            stats: self.stats.clone(),
            me: self.args.index,
        });
        // Before any thread starts: they inherit it.
        batch_scheduling();
        for t in 0..self.cfg.env_threads.clamp(1, self.block_envs) {
            let s = shared.clone();
            let scope = self.thread_scope;
            let started = std::thread::Builder::new()
                .name(format!("rg-env-{t}"))
                .spawn(move || match scope {
                    Some(scope) => scope(&mut || env_thread(s.clone())),
                    None => env_thread(s),
                });
            if let Err(e) = started {
                stop_env_threads(&shared);
                return Err(WorkerError::Msg(format!("cannot start an env thread: {e}")));
            }
        }
        Ok(Some(shared))
    }

    /// Envs `done` on their threads: each finished env's record and books written
    /// ([`Worker::finish`]), its place in `busy` freed; then the whole answer of each command
    /// whose envs are all done.
    pub(super) fn take_done(
        &mut self,
        done: Vec<Done>,
        busy: &mut [Option<u64>],
        running: &mut Vec<Running>,
        finished: &mut Finished,
    ) -> Result<(), WorkerError> {
        for d in done {
            let Some(seq) = busy[d.j].take() else {
                continue;
            };
            if let Some(r) = running.iter_mut().find(|r| r.seq == seq) {
                self.finish(r, d, finished);
            }
        }
        let mut k = 0;
        while k < running.len() {
            if running[k].remaining > 0 {
                k += 1;
                continue;
            }
            let r = running.remove(k);
            if !r.partial {
                self.answer_whole(r)?;
            }
        }
        Ok(())
    }

    /// Start a reset or step: its envs' jobs go to the env threads, each to write its rows in
    /// the slot `targets` names for it.
    pub(super) fn start_command(
        &mut self,
        shared: &Shared,
        inc: Incoming,
        targets: Vec<u64>,
        extras: Result<(), EnvFault>,
    ) -> Result<Running, WorkerError> {
        let envs: Vec<usize> = (0..self.block_envs).filter(|&j| targets[j] != 0).collect();
        let Incoming {
            seq,
            command,
            payload,
        } = inc;
        let kind = command.serve().unwrap_or(Serve::Reset);
        self.stats.add(self.args.index, Counter::Commands, 1);
        let mut areas: Vec<[Area; 3]> = Vec::with_capacity(envs.len());
        for &j in &envs {
            let rows = self.slot_rows(targets[j]);
            let e = self.first_env + j;
            // SAFETY: env `e`'s rows of the slot this command names for it, this worker's
            // while the command is in flight (see `serve`).
            unsafe {
                areas.push([
                    Area::of(rows.obs_rows(e..e + 1)),
                    Area::of(rows.final_rows(e..e + 1)),
                    Area::of(rows.extra_rows(e..e + 1)),
                ]);
            }
        }
        let mut r = Running {
            seq,
            targets,
            partial: command.partial,
            remaining: envs.len(),
            answer: AnswerBuilder::default(),
            apart: Vec::new(),
            fault: extras.err(),
        };
        if r.fault.is_some() {
            r.remaining = 0;
            return Ok(r);
        }
        let per_env = if kind == Serve::Step {
            self.action_words
        } else {
            1
        };
        let ctx = Arc::new(Ctx {
            seeds: self.seeds.clone(),
            num_envs: self.cfg.num_envs as u64,
            autoreset: self.cfg.autoreset,
            action_bytes: self.action_bytes,
            n_info: self.n_info,
        });
        let mut q = guard(&shared.jobs);
        let jobs = envs.len();
        for (&j, [obs, fin, extra]) in envs.iter().zip(areas) {
            q.push_back(Job {
                j,
                kind,
                words: payload[j * per_env..(j + 1) * per_env].to_vec(),
                obs,
                fin,
                extra,
                ctx: ctx.clone(),
            });
        }
        drop(q);
        for _ in 0..jobs {
            shared.job_ready.notify_one();
        }
        Ok(r)
    }

    /// An env of command `r` is done: its record written, its books (both copies: the envs of
    /// a worker answer at different commands), its rows counted for the answer.
    fn finish(&mut self, r: &mut Running, d: Done, finished: &mut Finished) {
        let me = self.args.index;
        r.remaining -= 1;
        self.stats.add(me, Counter::EnvNs, d.wall_ns);
        self.stats.add(me, Counter::EnvSteps, 1);
        let (rec, info) = match d.result {
            Ok(v) => v,
            Err(f) => {
                if r.partial {
                    finished.failed.push((d.j, f));
                } else {
                    r.fault.get_or_insert(f);
                }
                return;
            }
        };
        {
            let envs = match &self.envs {
                WorkerEnvs::Shared(envs) => envs,
                _ => return,
            };
            let s = lock(&envs[d.j]);
            let e = self.first_env + d.j;
            self.books.write(r.seq, e, s.episode, s.seed);
            self.books.write(r.seq + 1, e, s.episode, s.seed);
        }
        let xb = self.slot_layout.extra_bytes;
        let rows = self.slot_rows(r.targets[d.j]);
        let e = self.first_env + d.j;
        rows.record(e, &rec);
        // SAFETY: env `e`'s room, written by its job, which is done.
        let room = unsafe { rows.extra_rows(e..e + 1) };
        let into = if r.partial {
            &mut finished.answer
        } else {
            &mut r.answer
        };
        into.add(&rec, &room[..xb.min(room.len())]);
        if rec.extra_apart() {
            let apart = if r.partial {
                &mut finished.apart
            } else {
                &mut r.apart
            };
            apart.push((d.j as u32, info));
        }
        if r.partial {
            finished.rows.push(d.j as u64);
        }
    }

    /// Publish the answer of a command whose envs are all done (one answer for them all).
    pub(super) fn answer_whole(&mut self, r: Running) -> Result<(), WorkerError> {
        let written = match r.fault {
            Some(f) => Err(f),
            None => self.write_apart_of(r.seq, &r.apart),
        };
        if let Err(f) = written {
            return self.report(r.seq, &f);
        }
        let answer = r.answer.finish(self.block_envs);
        self.publish_answer(r.seq, BlockKind::Data, Some(&answer), &[])
    }

    /// Publish what partial commands finished, while the supervisor has taken enough of this
    /// worker's answers (see the module docs): each failed env in an error answer, the others
    /// together in one [`BlockKind::Rows`] answer.
    pub(super) fn answer_partial(&mut self, finished: &mut Finished) -> Result<(), WorkerError> {
        while let Some((j, f)) = finished.failed.first().cloned() {
            if !self.may_answer() {
                return Ok(());
            }
            finished.failed.remove(0);
            let n = self.next_answer_no();
            let path = env_fault_path_of(&self.id, self.args.index, self.args.generation, n);
            f.write(&path).map_err(WorkerError::Msg)?;
            self.publish_answer(n, BlockKind::Error, None, &[j as u64])?;
        }
        if finished.rows.is_empty() || !self.may_answer() {
            return Ok(());
        }
        let f = std::mem::take(finished);
        let n = self.next_answer_no();
        let mut answer = f.answer.finish(f.rows.len());
        if !f.apart.is_empty() {
            self.write_apart(n, &f.apart).map_err(WorkerError::Msg)?;
            answer.apart = true;
        }
        self.publish_answer(n, BlockKind::Rows, Some(&answer), &f.rows)
    }

    /// Whether the supervisor has taken enough of this worker's answers for one more.
    fn may_answer(&self) -> bool {
        self.answers
            .saturating_sub(self.stats.taken(self.args.index))
            < UNTAKEN
    }

    /// The number of this worker's next answer to partial commands (its header's `seq`,
    /// which names its side files); counts down from the top, apart from command numbers.
    fn next_answer_no(&mut self) -> u64 {
        self.answer_no += 1;
        u64::MAX / 2 + self.answer_no
    }
}
