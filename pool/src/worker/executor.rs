//! The worker's one executor: its loop over commands, whether its envs run inline or on
//! threads of their own (`env_concurrency`).
//!
//! The loop takes commands from the port into a queue, starts them in order (a command waits
//! until every env it names is idle), and publishes the answers. A reset or step is served
//! inline when the worker has no env threads (every env of the command, or the vector env of
//! the block, on the worker's own thread: [`Worker::serve_inline`]), its answer published at
//! once; on env threads, its envs' jobs go to them and each finished env comes back to this
//! loop, which writes its record and answers (`concurrent.rs`). Either way one command check
//! ([`Worker::check_command`], [`Named`]), one choice of output area ([`Worker::slot_rows`]),
//! one side-file writer ([`Worker::write_apart`]) and one publisher
//! ([`Worker::publish_answer`]: an iceoryx2 sample of answer words and, for a partial answer,
//! its rows), all here.
//!
//! How the loop waits: on one listener, for both commands and finished envs (env threads
//! wake it). Inline, it polls first for a command it expects soon, as the command before
//! said ([`Pace`], [`expected_poll`]); with env threads it blocks at once, the cores being
//! theirs.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use rogue_gym_ipc::{BlockHeader, WaitCall, WaitPolicy, hybrid_wait};

use super::concurrent::{Finished, Running};
use super::env_threads::{Shared, guard};
use super::envs::take_action_extras;
use super::{Incoming, Worker, WorkerError};
use crate::stats::{Counter, ns_since, stamp};
use crate::wire::answer::{ANSWER_WORDS, Answer, BlockKind, sample_words};
use crate::wire::slot_layout::SlotRows;
use crate::wire::{Command, EnvFault, Op, Pace, Serve, calls, extra_apart_path};

/// The longest a worker polls for a command it expects soon ([`expected_poll`]).
const MAX_EXPECTED_POLL: Duration = Duration::from_millis(2);
/// How often a worker that holds finished envs checks whether answers were taken
/// (`concurrent.rs`).
const HOLD_CHECK: Duration = Duration::from_millis(1);

/// How long to poll for the next command: twice the last gap between an answer and the next
/// command when that was short (a caller in a tight loop: the worker is still polling when
/// the command comes, and no wake-up is paid), else the configured budget.
pub(super) fn expected_poll(budget: Duration, last_gap: Duration) -> Duration {
    if last_gap <= MAX_EXPECTED_POLL / 2 {
        budget.max(last_gap * 2)
    } else {
        budget
    }
}

/// How a worker waits for its next command: as the command before said ([`Pace`]).
struct Pacing {
    policy: WaitPolicy,
    pace: Pace,
    /// How long the last command took to come after the answer before it.
    last_gap: Duration,
}

impl Pacing {
    /// The policy of the next wait (`threads`: the envs run on threads, whose cores a poll
    /// would take: block at once).
    fn now(&self, threads: bool) -> WaitPolicy {
        let poll_budget = match self.pace {
            _ if threads => Duration::ZERO,
            Pace::Expected => expected_poll(self.policy.poll_budget, self.last_gap),
            Pace::Short => self.policy.poll_budget,
            Pace::Block => Duration::ZERO,
        };
        WaitPolicy {
            poll_budget,
            ..self.policy
        }
    }
}

/// What the loop keeps between its turns.
struct Queue {
    /// Commands taken and not started, in order; payload buffers to reuse.
    waiting: VecDeque<Incoming>,
    spare: Vec<Vec<u64>>,
    /// Envs of the block a started command still runs, and which command each belongs to.
    busy: Vec<Option<u64>>,
    /// Commands started and not answered whole (env threads only).
    running: Vec<Running>,
    /// Finished envs of partial commands, for the next answer.
    finished: Finished,
}

impl Worker<'_> {
    /// Serve commands until the supervisor closes the worker (or is gone).
    pub(super) fn run(&mut self) -> Result<(), WorkerError> {
        let threads = self.start_env_threads()?;
        let result = self.serve_commands(threads.as_deref());
        if let Some(shared) = threads {
            super::concurrent::stop_env_threads(&shared);
        }
        result
    }

    /// The loop (see the module docs).
    fn serve_commands(&mut self, threads: Option<&Shared>) -> Result<(), WorkerError> {
        let mut pacing = Pacing {
            policy: WaitPolicy {
                poll_budget: Duration::from_micros(self.cfg.poll_budget_us),
                block_slice: Duration::from_millis(self.cfg.block_slice_ms.max(1)),
                yield_cpu: self.cfg.poll_yield,
                sleep_first: Duration::ZERO,
            },
            pace: Pace::Expected,
            last_gap: Duration::MAX,
        };
        let mut q = Queue {
            waiting: VecDeque::new(),
            spare: Vec::new(),
            busy: vec![None; self.block_envs],
            running: Vec::new(),
            finished: Finished::default(),
        };
        loop {
            if let Some(shared) = threads {
                let done = std::mem::take(&mut *guard(&shared.done));
                self.take_done(done, &mut q.busy, &mut q.running, &mut q.finished)?;
                self.answer_partial(&mut q.finished)?;
            }
            if self.start_waiting(threads, &mut q)? {
                return Ok(()); // closed
            }
            self.wait_for_work(&mut pacing, threads, &mut q)?;
        }
    }

    /// Before a reset or step is served, inline or on threads: the seed schedule re-read
    /// where the command says, and a step's action extras handed to its envs (their failure is
    /// the command's, answered as its env fault).
    fn prepare(
        &mut self,
        command: &Command,
        kind: Serve,
    ) -> Result<Result<(), EnvFault>, WorkerError> {
        if command.reload_seeds {
            self.seeds = super::setup::read_config(&self.args.config)
                .map_err(WorkerError::Msg)?
                .seeds;
        }
        if kind != Serve::Step || !command.action_extras {
            return Ok(Ok(()));
        }
        let me = (self.args.index, self.args.generation);
        Ok(take_action_extras(
            &self.id,
            me,
            &mut self.envs,
            self.first_env as u64,
        ))
    }

    /// Start what the queue holds, in order, while the envs it names are idle; `true` when
    /// the supervisor closed the worker.
    fn start_waiting(
        &mut self,
        threads: Option<&Shared>,
        q: &mut Queue,
    ) -> Result<bool, WorkerError> {
        let epw = self.block_envs;
        while let Some(next) = q.waiting.front() {
            let idle = q.busy.iter().all(Option::is_none);
            match next.command.serve() {
                None if next.command.op == Op::Close => return Ok(true),
                None if !idle => break,
                None => {
                    let seq = next.seq;
                    self.answer_calls(seq)?;
                }
                Some(kind) => {
                    let named = self.check_command(next.seq, &next.command, &next.payload)?;
                    let Some(shared) = threads else {
                        let ready = self.prepare(&next.command, kind)?;
                        self.serve_inline(next.seq, kind, &named, ready)?;
                        let done = q.waiting.pop_front();
                        q.spare.extend(done.map(|inc| inc.payload));
                        continue;
                    };
                    let targets: Vec<u64> = (0..epw).map(|j| named.slots.of(j)).collect();
                    if (0..epw).any(|j| targets[j] != 0 && q.busy[j].is_some()) {
                        break;
                    }
                    let Some(inc) = q.waiting.pop_front() else {
                        break;
                    };
                    // Once, as it starts (its action extras are read once).
                    let ready = self.prepare(&inc.command, kind)?;
                    let r = self.start_command(shared, inc, targets, ready)?;
                    if r.remaining == 0 {
                        // Failed before any env started (its action extras): answered now.
                        self.answer_whole(r)?;
                        continue;
                    }
                    for (j, b) in q.busy.iter_mut().enumerate() {
                        if r.targets[j] != 0 {
                            *b = Some(r.seq);
                        }
                    }
                    q.running.push(r);
                    continue;
                }
            }
            let done = q.waiting.pop_front();
            q.spare.extend(done.map(|inc| inc.payload));
        }
        Ok(false)
    }

    /// Wait until there is something to do: a command in the port (taken into the queue), an
    /// env done on its thread, or (answers held back) the time to look at them again.
    fn wait_for_work(
        &mut self,
        pacing: &mut Pacing,
        threads: Option<&Shared>,
        q: &mut Queue,
    ) -> Result<(), WorkerError> {
        let ppid = self.args.ppid;
        let holding = !q.finished.rows.is_empty() || !q.finished.failed.is_empty();
        let deadline = holding.then(|| Instant::now() + HOLD_CHECK);
        let idle = q.running.is_empty();
        let (waiting, since) = (stamp(), Instant::now());
        let mut took = false;
        let policy = pacing.now(threads.is_some());
        hybrid_wait::<WorkerError>(self.ports.cmd_listener(), &policy, deadline, |call| {
            if call == WaitCall::Idle && nix::unistd::getppid().as_raw() != ppid {
                return Err(WorkerError::ParentGone(ppid));
            }
            while let Some(cmd) = self.ports.try_recv_cmd()? {
                let h = *cmd.user_header();
                let command = Command::decode(h.kind)
                    .map_err(|e| WorkerError::Msg(format!("command {}: {e}", h.seq)))?;
                let n = (h.len as usize).min(cmd.payload().len());
                let mut payload = q.spare.pop().unwrap_or_default();
                payload.clear();
                payload.extend_from_slice(&cmd.payload()[..n]);
                pacing.pace = command.pace;
                q.waiting.push_back(Incoming {
                    seq: h.seq,
                    command,
                    payload,
                });
                self.stats.read_one(self.args.index);
                took = true;
            }
            Ok(took || threads.is_some_and(|s| !guard(&s.done).is_empty()))
        })?;
        if took {
            pacing.last_gap = since.elapsed();
        }
        if idle {
            self.stats
                .add(self.args.index, Counter::WaitNs, ns_since(waiting));
        }
        Ok(())
    }

    /// [`Op::Call`]: env calls, off the hot path.
    fn answer_calls(&mut self, seq: u64) -> Result<(), WorkerError> {
        let me = (self.args.index, self.args.generation);
        match super::envs::answer_calls(&self.id, me, &mut self.envs, self.first_env as u64) {
            Ok(()) => self.send(seq, BlockKind::Call),
            Err(f) => self.report(seq, &f),
        }
    }
}

/// The slot (`s + 1`) each env of the block writes in under a reset or step.
#[derive(Clone, Copy)]
pub(super) enum Slots<'p> {
    /// Every env into this one.
    All(u64),
    /// Each env into its own (a [`Command::subset`] command; 0: left alone).
    Each(&'p [u64]),
}

impl Slots<'_> {
    /// The slot (`s + 1`) of the block's env `j`; 0: not one of the command's.
    pub(super) fn of(self, j: usize) -> u64 {
        match self {
            Slots::All(t) => t,
            Slots::Each(t) => t[j],
        }
    }

    /// The slots written, each once, in order (`1..=slots`).
    pub(super) fn written(self, slots: u64) -> impl Iterator<Item = u64> {
        (1..=slots).filter(move |s| match self {
            Slots::All(t) => t == *s,
            Slots::Each(t) => t.contains(s),
        })
    }
}

/// A reset or step's payload, checked: its words per env (an episode index for a reset, the
/// action words for a step), those words, and each env's slot.
pub(super) struct Named<'p> {
    pub(super) per_env: usize,
    pub(super) words: &'p [u64],
    pub(super) slots: Slots<'p>,
}

impl Worker<'_> {
    /// Check command `seq`'s `payload` (a reset or step): as many words as the block's envs
    /// take, and every slot in the pool. The one check of both executors: an error ends the
    /// worker (the supervisor sent what no supervisor sends).
    pub(super) fn check_command<'p>(
        &self,
        seq: u64,
        command: &Command,
        payload: &'p [u64],
    ) -> Result<Named<'p>, WorkerError> {
        let epw = self.block_envs;
        let per_env = if command.op == Op::Step {
            self.action_words
        } else {
            1
        };
        let subset = command.subset;
        let n = payload.len();
        if n != epw * per_env + if subset { epw } else { 0 } {
            return Err(WorkerError::Msg(format!(
                "command {seq} carries {n} words for {epw} envs of {per_env} words (subset: \
                 {subset})"
            )));
        }
        let slots = self.cfg.batch_slots as u64;
        let (words, each) = payload.split_at(epw * per_env);
        let (named, bad) = if subset {
            (Slots::Each(each), each.iter().copied().find(|&w| w > slots))
        } else {
            let t = u64::from(command.target);
            (Slots::All(t), (!(1..=slots).contains(&t)).then_some(t))
        };
        if let Some(t) = bad {
            return Err(WorkerError::Msg(format!(
                "command {seq}: observation target {t}, but the pool has {slots} slots"
            )));
        }
        Ok(Named {
            per_env,
            words,
            slots: named,
        })
    }
}

impl Worker<'_> {
    /// The rows of batch slot `target - 1` (`target` checked: 1 to `batch_slots`).
    pub(super) fn slot_rows(&self, target: u64) -> SlotRows {
        // SAFETY: `target <= batch_slots` (every command's slots are checked,
        // `check_command`): inside the batch buffer, 64-byte aligned.
        unsafe {
            let base = self
                .batch
                .as_ptr()
                .add((target as usize - 1) * self.slot_layout.bytes());
            self.slot_layout.rows(base)
        }
    }

    /// Write the extra info that did not fit its rooms (`(row, bytes)`) beside answer `n`, in
    /// a private file named by it; the supervisor takes it with the answer.
    pub(super) fn write_apart(&self, n: u64, apart: &[(u32, Vec<u8>)]) -> Result<(), String> {
        let entries: Vec<(u32, &[u8])> = apart.iter().map(|(j, b)| (*j, b.as_slice())).collect();
        let path = extra_apart_path(&self.id, self.args.index, self.args.generation, n);
        calls::write(&path, &calls::encode(&entries))
    }

    /// [`Worker::write_apart`] for a command's answer: a failure is its first env's fault.
    pub(super) fn write_apart_of(&self, n: u64, apart: &[(u32, Vec<u8>)]) -> Result<(), EnvFault> {
        match apart.first() {
            None => Ok(()),
            Some((j, _)) => self.write_apart(n, apart).map_err(|e| {
                EnvFault::new(
                    (self.first_env as u64) + u64::from(*j),
                    "extra info",
                    format!("cannot write the info that did not fit its room: {e}"),
                )
            }),
        }
    }

    /// Publish answer `n` of kind `kind`: `answer`'s words (none: a zero word, naming no
    /// rows) and, for a partial answer, the rows of the block it is for.
    pub(super) fn publish_answer(
        &mut self,
        n: u64,
        kind: BlockKind,
        answer: Option<&Answer>,
        rows: &[u64],
    ) -> Result<(), WorkerError> {
        let mut block = self.ports.loan_block(sample_words(self.block_envs))?;
        *block.user_header_mut() = self.header(n, kind);
        let p = block.payload_mut();
        let at = match answer {
            Some(a) => {
                p[..ANSWER_WORDS].copy_from_slice(&a.encode());
                ANSWER_WORDS
            }
            None => 0,
        };
        if rows.is_empty() {
            if answer.is_none() {
                p[0] = 0;
            }
        } else {
            p[at] = rows.len() as u64;
            p[at + 1..at + 1 + rows.len()].copy_from_slice(rows);
        }
        let t = stamp();
        self.ports.send_block(block)?;
        self.answers += 1;
        self.stats
            .add(self.args.index, Counter::PublishNs, ns_since(t));
        Ok(())
    }

    /// Send an answer without data (`kind`) to command `seq`.
    pub(super) fn send(&mut self, seq: u64, kind: BlockKind) -> Result<(), WorkerError> {
        self.publish_answer(seq, kind, None, &[])
    }

    fn header(&self, seq: u64, kind: BlockKind) -> BlockHeader {
        BlockHeader {
            seq,
            generation: self.args.generation,
            worker: self.args.index as u32,
            kind: kind.word(),
            ready_ns: 0,
        }
    }

    /// Report env fault `f` as the answer to command `seq` (the supervisor raises it to the
    /// caller and requires a reset); the worker itself is fine and serves on.
    pub(super) fn report(&mut self, seq: u64, f: &EnvFault) -> Result<(), WorkerError> {
        f.write(&self.fault_path).map_err(WorkerError::Msg)?;
        self.send(seq, BlockKind::Error)
    }
}
