//! A worker whose envs run on threads (`WorkerConfig::env_threads` > 0): for envs that wait (a
//! socket, a remote simulator, a subprocess, a sleep), so that an env that waits holds its own
//! thread only, not its worker-mates.
//!
//! Two kinds of thread:
//!
//! * **env threads** (`env_threads` of them, `env_threads.rs`) take jobs, one env's reset or
//!   step each, from one queue; the env writes its observation, final observation and extra
//!   info straight into its own rows of the batch slot the command names for it, as the serial
//!   loop does; each env is behind a lock, taken by one thread at a time. A job done goes to
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
//! What holds as in the serial loop: each env's trajectory (its state is its own), an env
//! that fails fails alone (an error answer names it; the others go on), and a worker that dies
//! costs its envs one restarted episode. What differs: a command's envs finish in any order,
//! and streaming stores are off (each thread writes its env's rows).

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, PoisonError, RwLock};
use std::time::{Duration, Instant};

use rogue_gym_ipc::CmdWaker;
use rogue_gym_ipc::iceoryx2::port::listener::ListenerWaitError;

use super::env_threads::{Area, Ctx, Done, Job, Shared, batch_scheduling, env_thread, guard};
use super::envs::{WorkerEnvs, lock, take_action_extras};
use super::{Worker, WorkerError};
use crate::stats::Counter;
use crate::wire::answer::{ANSWER_WORDS, AnswerBuilder, BlockKind, sample_words};
use crate::wire::slot_layout::SlotRows;
use crate::wire::{Command, EnvFault, Op, Serve, calls, env_fault_path_of, extra_apart_path};

/// Answers a worker may have untaken before it holds its finished envs (the answer port
/// holds four; one is left for an answer that cannot wait, an error's).
const UNTAKEN: u64 = 3;
/// How often a worker that holds finished envs checks whether answers were taken.
const HOLD_CHECK: Duration = Duration::from_millis(1);

/// A command taken from the port: its sequence number, the command, its payload.
struct Incoming {
    seq: u64,
    command: Command,
    payload: Vec<u64>,
}

/// A command started and not yet answered whole.
struct Running {
    seq: u64,
    /// The slot (`s + 1`) each env of the block writes in (0: not one of the command's).
    targets: Vec<usize>,
    partial: bool,
    /// Its envs not done yet.
    remaining: usize,
    answer: AnswerBuilder,
    apart: Vec<(u32, Vec<u8>)>,
    /// The first env that failed.
    fault: Option<EnvFault>,
}

/// Finished envs of partial commands, for the next answer.
#[derive(Default)]
struct Finished {
    rows: Vec<u64>,
    answer: AnswerBuilder,
    apart: Vec<(u32, Vec<u8>)>,
    /// Envs that failed, with their fault: an error answer each.
    failed: Vec<(usize, EnvFault)>,
}

impl Worker<'_> {
    /// Serve commands with the envs on `threads` threads until the supervisor closes the
    /// worker (or is gone).
    pub(super) fn run_concurrent(&mut self, threads: usize) -> Result<(), WorkerError> {
        let WorkerEnvs::Shared(envs) = &self.envs else {
            return Err(WorkerError::Msg("envs on threads need one env each".into()));
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
        for t in 0..threads.clamp(1, self.block_envs) {
            let s = shared.clone();
            let scope = self.thread_scope;
            std::thread::Builder::new()
                .name(format!("rg-env-{t}"))
                .spawn(move || match scope {
                    Some(scope) => scope(&mut || env_thread(s.clone())),
                    None => env_thread(s),
                })
                .map_err(|e| WorkerError::Msg(format!("cannot start an env thread: {e}")))?;
        }
        let result = self.serve_concurrently(&shared);
        // Threads stuck in an env's wait are not joined: the process exits with them.
        shared.stop.store(true, Ordering::Relaxed);
        shared.job_ready.notify_all();
        drop(
            (shared.waker.write())
                .unwrap_or_else(PoisonError::into_inner)
                .take(),
        );
        result
    }

    /// The worker's own thread (see the module docs).
    fn serve_concurrently(&mut self, shared: &Shared) -> Result<(), WorkerError> {
        let epw = self.block_envs;
        // The wait blocks at once: the cores are the env threads' (a poll would take them from
        // envs that compute between their waits), and a wake-up is small beside an env's wait.
        let block_slice = Duration::from_millis(self.cfg.block_slice_ms.max(1));
        let mut alive_checked = Instant::now();
        let mut queue: VecDeque<Incoming> = VecDeque::new();
        let mut busy = vec![false; epw];
        // Which running command each busy env belongs to.
        let mut of_env: Vec<Option<u64>> = vec![None; epw];
        let mut running: Vec<Running> = Vec::new();
        let mut finished = Finished::default();
        loop {
            if alive_checked.elapsed() >= block_slice {
                let ppid = self.args.ppid;
                if nix::unistd::getppid().as_raw() != ppid {
                    return Err(WorkerError::ParentGone(ppid));
                }
                alive_checked = Instant::now();
            }
            let took = self.take_commands(&mut queue)?;
            let done = std::mem::take(&mut *guard(&shared.done));
            if !took && done.is_empty() {
                // Nothing new: wait until a command or a finished env wakes the listener, or
                // until it is time to look at held answers again.
                let holding = !finished.rows.is_empty() || !finished.failed.is_empty();
                let slice = if holding { HOLD_CHECK } else { block_slice };
                match self.ports.cmd_listener().timed_wait(|_| {}, slice) {
                    Ok(_) | Err(ListenerWaitError::InterruptSignal) => {}
                    Err(e) => {
                        return Err(WorkerError::Msg(format!(
                            "wait on the command listener: {e:?}"
                        )));
                    }
                }
                if !holding {
                    continue;
                }
            }
            for d in done {
                let j = d.j;
                busy[j] = false;
                let Some(seq) = of_env[j].take() else {
                    continue;
                };
                let Some(r) = running.iter_mut().find(|r| r.seq == seq) else {
                    continue;
                };
                self.finish(r, d, &mut finished);
            }
            // Whole answers of the commands that are done.
            let mut k = 0;
            while k < running.len() {
                if running[k].remaining == 0 && !running[k].partial {
                    let r = running.remove(k);
                    self.answer_whole(r)?;
                } else if running[k].remaining == 0 {
                    running.remove(k);
                } else {
                    k += 1;
                }
            }
            self.answer_partial(&mut finished)?;
            // Start what the queue holds, in order, while its envs are idle.
            while let Some(next) = queue.front() {
                match next.command.op {
                    Op::Close => return Ok(()),
                    Op::Call if busy.iter().any(|&b| b) => break,
                    Op::Call => {
                        let seq = next.seq;
                        queue.pop_front();
                        self.answer_calls(seq)?;
                    }
                    Op::Reset | Op::Step => {
                        let targets = self.named_envs(next)?;
                        let envs: Vec<usize> = (0..epw).filter(|&j| targets[j] != 0).collect();
                        if envs.iter().any(|&j| busy[j]) {
                            break;
                        }
                        let Some(inc) = queue.pop_front() else { break };
                        let r = self.start_command(shared, inc, targets, &envs)?;
                        for &j in &envs {
                            busy[j] = true;
                            of_env[j] = Some(r.seq);
                        }
                        running.push(r);
                    }
                }
            }
        }
    }

    /// Take every command the port holds into `queue`; whether there was one.
    fn take_commands(&mut self, queue: &mut VecDeque<Incoming>) -> Result<bool, WorkerError> {
        let mut took = false;
        while let Some(cmd) = self.ports.try_recv_cmd()? {
            let h = *cmd.user_header();
            let command = Command::decode(h.kind)
                .map_err(|e| WorkerError::Msg(format!("command {}: {e}", h.seq)))?;
            let n = (h.len as usize).min(cmd.payload().len());
            queue.push_back(Incoming {
                seq: h.seq,
                command,
                payload: cmd.payload()[..n].to_vec(),
            });
            self.stats.read_one(self.args.index);
            took = true;
        }
        Ok(took)
    }

    /// The slot (`s + 1`) each env of the block writes in under a reset or step, 0 for the
    /// envs it does not name; its payload checked.
    fn named_envs(&self, inc: &Incoming) -> Result<Vec<usize>, WorkerError> {
        let epw = self.block_envs;
        let step = inc.command.op == Op::Step;
        let per_env = if step { self.action_words } else { 1 };
        let subset = inc.command.subset;
        let n = inc.payload.len();
        if n != epw * per_env + if subset { epw } else { 0 } {
            return Err(WorkerError::Msg(format!(
                "command {} carries {n} words for {epw} envs of {per_env} words (subset: {subset})",
                inc.seq
            )));
        }
        let slots = self.cfg.batch_slots;
        let targets: Vec<usize> = if subset {
            inc.payload[epw * per_env..]
                .iter()
                .map(|&w| w as usize)
                .collect()
        } else {
            vec![inc.command.target as usize; epw]
        };
        if let Some(t) = targets.iter().find(|&&t| t > slots || (!subset && t == 0)) {
            return Err(WorkerError::Msg(format!(
                "command {}: observation target {t}, but the pool has {slots} slots",
                inc.seq
            )));
        }
        Ok(targets)
    }

    /// Start a reset or step: its envs' jobs go to the env threads, each to write its rows in
    /// the slot `targets` names for it.
    fn start_command(
        &mut self,
        shared: &Shared,
        inc: Incoming,
        targets: Vec<usize>,
        envs: &[usize],
    ) -> Result<Running, WorkerError> {
        let Incoming {
            seq,
            command,
            payload,
        } = inc;
        let kind = command.serve().unwrap_or(Serve::Reset);
        if command.reload_seeds {
            self.seeds = super::setup::read_config(&self.args.config)
                .map_err(WorkerError::Msg)?
                .seeds;
        }
        self.stats.add(self.args.index, Counter::Commands, 1);
        let mut areas: Vec<[Area; 3]> = Vec::with_capacity(envs.len());
        for &j in envs {
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
            fault: None,
        };
        if kind == Serve::Step && command.action_extras {
            let me = (self.args.index, self.args.generation);
            if let Err(f) = take_action_extras(&self.id, me, &mut self.envs, self.first_env as u64)
            {
                r.fault = Some(f);
            }
        }
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

    /// The rows of slot `target - 1`.
    fn slot_rows(&self, target: usize) -> SlotRows {
        // SAFETY: `target <= batch_slots` (checked by the caller): inside the batch buffer,
        // 64-byte aligned.
        unsafe {
            let base = self
                .batch
                .as_ptr()
                .add((target - 1) * self.slot_layout.bytes());
            self.slot_layout.rows(base)
        }
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
    fn answer_whole(&mut self, r: Running) -> Result<(), WorkerError> {
        if let Some(f) = r.fault {
            f.write(&self.fault_path).map_err(WorkerError::Msg)?;
            return self.send(r.seq, BlockKind::Error);
        }
        if !r.apart.is_empty() {
            let entries: Vec<(u32, &[u8])> =
                r.apart.iter().map(|(j, b)| (*j, b.as_slice())).collect();
            let path = extra_apart_path(&self.id, self.args.index, self.args.generation, r.seq);
            calls::write(&path, &calls::encode(&entries)).map_err(WorkerError::Msg)?;
        }
        let mut block = self.ports.loan_block(sample_words(self.block_envs))?;
        *block.user_header_mut() = self.header(r.seq, BlockKind::Data);
        let answer = r.answer.finish(self.block_envs);
        block.payload_mut()[..ANSWER_WORDS].copy_from_slice(&answer.encode());
        self.publish(block)
    }

    /// Publish what partial commands finished, while the supervisor has taken enough of this
    /// worker's answers (see the module docs): each failed env in an error answer, the others
    /// together in one [`BlockKind::Rows`] answer.
    fn answer_partial(&mut self, finished: &mut Finished) -> Result<(), WorkerError> {
        while let Some((j, f)) = finished.failed.first().cloned() {
            if !self.may_answer() {
                return Ok(());
            }
            finished.failed.remove(0);
            let n = self.next_answer_no();
            f.write(&env_fault_path_of(
                &self.id,
                self.args.index,
                self.args.generation,
                n,
            ))
            .map_err(WorkerError::Msg)?;
            let mut block = self.ports.loan_block(sample_words(self.block_envs))?;
            *block.user_header_mut() = self.header(n, BlockKind::Error);
            block.payload_mut()[..2].copy_from_slice(&[1, j as u64]);
            self.publish(block)?;
        }
        if finished.rows.is_empty() || !self.may_answer() {
            return Ok(());
        }
        let f = std::mem::take(finished);
        let n = self.next_answer_no();
        let mut answer = f.answer.finish(f.rows.len());
        if !f.apart.is_empty() {
            let entries: Vec<(u32, &[u8])> =
                f.apart.iter().map(|(j, b)| (*j, b.as_slice())).collect();
            let path = extra_apart_path(&self.id, self.args.index, self.args.generation, n);
            calls::write(&path, &calls::encode(&entries)).map_err(WorkerError::Msg)?;
            answer.apart = true;
        }
        let mut block = self.ports.loan_block(sample_words(self.block_envs))?;
        *block.user_header_mut() = self.header(n, BlockKind::Rows);
        let p = block.payload_mut();
        p[..ANSWER_WORDS].copy_from_slice(&answer.encode());
        p[ANSWER_WORDS] = f.rows.len() as u64;
        p[ANSWER_WORDS + 1..ANSWER_WORDS + 1 + f.rows.len()].copy_from_slice(&f.rows);
        self.publish(block)
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
