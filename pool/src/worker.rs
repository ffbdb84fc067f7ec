//! The worker process: steps a block of envs, each env writing its rows (observation, record,
//! infos) in the pool's batch slot its command names, and publishes one answer word per
//! command through iceoryx2.
//!
//! Entry point: [`worker_main`], called by `rogue-gym worker ...`, by the e2e test binary and by
//! the Python extension (`python -m rogue_gym.worker ...`). Arguments (after the program and its
//! leading args): `--config <file> --index <k> --generation <g> --ppid <supervisor pid>
//! --shared-fds <batch>,<books>,<stats>` (the descriptors of the pool's buffers, which the
//! supervisor keeps open across the worker's `exec`).
//!
//! The worker is set up ([`worker_main`]; its command line and config in `setup.rs`) and
//! then one function per command op. Its envs are
//! stepped one after another (`envs.rs`, each env's state machine in `env_state.rs`), as one
//! [`crate::EnvBlock`] (`block.rs`), or each on a thread of its own (`concurrent.rs`, the
//! pool's `env_concurrency`); the rows and the answer are written in `block_out.rs`, written
//! with streaming stores for large batches (`streaming.rs`); `sabotage.rs` is the trust tests'
//! hook that makes a worker write bad values.

use std::path::PathBuf;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use rogue_gym_ipc::iceoryx2::node::Node;
use rogue_gym_ipc::{
    BlockHeader, IpcError, PoolId, SharedBuffer, Svc, WaitCall, WaitPolicy, WorkerPorts,
    hybrid_wait,
};

use crate::config::AutoresetMode;
use crate::env::MAX_INFO;
use crate::registry::{Built, EnvRegistry};
use crate::stats::{Counter, StatsBuffer, ns_since, stamp};
use crate::wire::answer::{ANSWER_WORDS, AnswerBuilder, BlockKind, sample_words};
use crate::wire::books::Books;
use crate::wire::slot_layout::SlotLayout;
use crate::wire::{
    BATCH_BUFFER, Command, EnvFault, Op, Pace, Serve, WorkerConfig, calls, env_fault_path,
    extra_apart_path, successor_marker,
};

mod block;
mod block_out;
mod concurrent;
mod env_state;
mod env_threads;
mod envs;
mod sabotage;
mod setup;
mod streaming;

use block::BlockHost;
use block_out::{BlockOut, Scratch};
use env_state::{EnvState, ServeCtx};
use envs::{WorkerEnvs, answer_calls, take_action_extras};
use setup::{Args, parse_args, pin_to_core, read_config, wait_for_go};

#[derive(Debug, thiserror::Error)]
enum WorkerError {
    #[error(transparent)]
    Ipc(#[from] IpcError),
    #[error("{0}")]
    Msg(String),
    #[error("the supervisor (pid {0}) is gone")]
    ParentGone(i32),
}

/// Run a worker; returns the process exit code (0: closed by the supervisor or supervisor gone,
/// 2: bad arguments or config, 3: env or transport failure). Messages go to stderr, which the
/// supervisor captures for crash reports. `args` are the arguments after the program name and
/// its leading args (see the module docs). `registry` must know the pool's env kind.
pub fn worker_main(args: &[String], registry: &EnvRegistry) -> i32 {
    let a = match parse_args(args) {
        Ok(a) => a,
        Err(e) => {
            eprintln!(
                "rogue-gym worker: {e}\nusage: worker --config <file> --index <k> --generation <g> --ppid <pid> --shared-fds <batch>,<books>,<stats>"
            );
            return 2;
        }
    };
    // Die with the supervisor; then close the race where it died before prctl.
    let _ = nix::sys::prctl::set_pdeathsig(nix::sys::signal::Signal::SIGKILL);
    if nix::unistd::getppid().as_raw() != a.ppid {
        eprintln!(
            "rogue-gym worker {}: supervisor {} already gone",
            a.index, a.ppid
        );
        return 0;
    }
    let cfg: WorkerConfig = match read_config(&a.config) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("rogue-gym worker {}: {e}", a.index);
            return 2;
        }
    };
    if let Some(core) = cfg.cpu_cores.as_ref().and_then(|c| c.get(a.index))
        && let Err(e) = pin_to_core(*core)
    {
        // Not fatal: the worker runs where the kernel puts it.
        eprintln!(
            "rogue-gym worker {}: cpu_affinity not applied: {e}",
            a.index
        );
    }
    match Worker::start(&a, &cfg, registry).and_then(|mut w| w.run()) {
        Ok(()) => 0,
        Err(WorkerError::ParentGone(p)) => {
            eprintln!("rogue-gym worker {}: supervisor {p} gone, exiting", a.index);
            0
        }
        Err(e) => {
            eprintln!(
                "rogue-gym worker {} (generation {}): {e}",
                a.index, a.generation
            );
            3
        }
    }
}

/// The longest a worker polls for a command it expects soon ([`expected_poll`]).
const MAX_EXPECTED_POLL: Duration = Duration::from_millis(2);

/// How long to poll for the next command: twice the last gap between an answer and the next
/// command when that was short (a caller in a tight loop: the worker is still polling when
/// the command comes, and no wake-up is paid), else the configured budget.
fn expected_poll(budget: Duration, last_gap: Duration) -> Duration {
    if last_gap <= MAX_EXPECTED_POLL / 2 {
        budget.max(last_gap * 2)
    } else {
        budget
    }
}

/// A running worker: its envs, its ports, and the pool's shared memory it writes.
struct Worker<'a> {
    args: &'a Args,
    cfg: &'a WorkerConfig,
    id: PoolId,
    envs: WorkerEnvs,
    /// The block's first env (a global id).
    first_env: usize,
    /// Info values per env, command words per action, raw action bytes (0: indices).
    n_info: usize,
    action_words: usize,
    action_bytes: usize,
    /// Envs of the worker's block, and the layout of a batch slot.
    block_envs: usize,
    slot_layout: SlotLayout,
    batch: SharedBuffer,
    stats: std::sync::Arc<StatsBuffer>,
    /// The scope the env threads of a worker whose envs run on threads live in
    /// ([`EnvRegistry::set_thread_scope`]).
    thread_scope: Option<crate::registry::ThreadScope>,
    books: Books,
    /// Dropped before the node they were made from.
    ports: WorkerPorts,
    /// The worker's node (a worker whose envs run on threads makes its `CmdWaker` from it).
    node: Node<Svc>,
    /// Answers published by this process (the supervisor counts those it took:
    /// `StatsBuffer::taken`), and answers to partial commands.
    answers: u64,
    answer_no: u64,
    /// The seed schedule (re-read when a reset says so).
    seeds: crate::seeds::SeedSchedule,
    /// The payload of the command being served.
    payload: Vec<u64>,
    scratch: Scratch,
    /// The rows are written with streaming stores ([`streaming`]).
    streamed: bool,
    fault_path: PathBuf,
    /// Reset and step commands served so far.
    served: u64,
}

/// How a worker waits for its next command: as the command before said ([`Pace`]).
struct Pacing {
    policy: WaitPolicy,
    pace: Pace,
    /// How long the last command took to come after the answer before it.
    last_gap: Duration,
}

impl Pacing {
    /// The policy of the next wait.
    fn now(&self) -> WaitPolicy {
        let poll_budget = match self.pace {
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

impl<'a> Worker<'a> {
    /// Build the envs of worker `a.index`, open the pool's shared memory and ports (a
    /// successor first waits for the worker it replaces to be gone), and say it is ready.
    fn start(
        a: &'a Args,
        cfg: &'a WorkerConfig,
        registry: &EnvRegistry,
    ) -> Result<Worker<'a>, WorkerError> {
        let envs = cfg.envs_of(a.index);
        if a.index >= cfg.num_workers || envs.is_empty() {
            return Err(WorkerError::Msg(format!(
                "worker index {} out of range (pool has {} workers for {} envs)",
                a.index, cfg.num_workers, cfg.num_envs
            )));
        }
        let id = PoolId::from_parts(&cfg.pool_name, &cfg.runtime_dir)?;
        // First thing: the pool's buffers, so that nothing this worker starts inherits them.
        // SAFETY: the supervisor opened these descriptors for this process (`--shared-fds`),
        // and nothing else here takes them.
        let [batch, books, stats] =
            unsafe { [0, 1, 2].map(|i| rogue_gym_ipc::buffer::take_inherited(a.shared_fds[i])) };
        let (batch, books, stats) = (batch?, books?, stats?);
        let fault_path = env_fault_path(&id, a.index, a.generation);
        let globals = envs.start as u64..envs.end as u64;
        let mut building = globals.start;
        let built = registry
            .make_block(&cfg.env, globals.clone(), |g| building = g)
            .map_err(|e| {
                // Reported like a failed step (the supervisor raises it rather than retrying).
                let fault = EnvFault::new(building, "construction", &e);
                let _ = fault.write(&fault_path);
                WorkerError::Msg(format!("cannot build env {building}: {e}"))
            })?;
        let each = |list: Vec<Box<dyn crate::Env>>| list.into_iter().zip(globals.clone());
        let (hosted, spec) = match built {
            Built::Envs(list) if cfg.env_threads > 0 => {
                let spec = list[0].spec();
                let envs = each(list).map(|(env, g)| Mutex::new(EnvState::new(env, g)));
                (WorkerEnvs::Shared(envs.collect()), spec)
            }
            Built::Envs(list) => {
                let spec = list[0].spec();
                let envs = each(list).map(|(env, g)| EnvState::new(env, g));
                (WorkerEnvs::Each(envs.collect()), spec)
            }
            Built::Block(block) => {
                let host = BlockHost::new(block, globals);
                let spec = host.spec();
                (WorkerEnvs::Block(host), spec)
            }
        };
        let n_info = spec.info_names.len().min(MAX_INFO);
        let slot_layout = SlotLayout {
            num_envs: cfg.num_envs,
            obs_bytes: spec.obs_bytes(),
            n_info,
            final_obs: cfg.autoreset == AutoresetMode::SameStep,
            extra_bytes: spec.extra_bytes,
        };
        let node = id.node(&format!("w{}g{}", a.index, a.generation))?;
        if a.successor {
            // The envs are built: the supervisor may now stop the worker this one replaces.
            rogue_gym_ipc::private::create_private_file(&successor_marker(
                &id,
                a.index,
                a.generation,
            ))?;
            wait_for_go(&id, a)?;
        }
        let ports = WorkerPorts::new(
            &node,
            a.index,
            sample_words(envs.len()),
            &cfg.channel_settings(),
        )?;
        let slots_bytes = cfg.batch_slots * slot_layout.bytes();
        // Envs write their observation to a stage first when the rows are streamed.
        let streamed = streaming::wanted(
            cfg.streaming_stores,
            cfg.batch_slots * cfg.num_envs * slot_layout.obs_bytes,
        );
        let scratch = Scratch {
            stage: if streamed {
                vec![0; slot_layout.obs_bytes]
            } else {
                Vec::new()
            },
            ..Scratch::default()
        };
        let action_words = spec.action_words();
        let mut w = Worker {
            args: a,
            cfg,
            batch: SharedBuffer::from_fd(batch, BATCH_BUFFER, slots_bytes)?,
            stats: std::sync::Arc::new(StatsBuffer::from_fd(stats, cfg.num_workers)?),
            books: Books::from_fd(books, cfg.num_envs)?,
            id,
            first_env: envs.start,
            envs: hosted,
            n_info,
            action_words,
            action_bytes: spec.action_bytes,
            block_envs: envs.len(),
            slot_layout,
            ports,
            node,
            answers: 0,
            answer_no: 0,
            seeds: cfg.seeds.clone(),
            payload: vec![0; envs.len() * (action_words + 1)],
            scratch,
            streamed,
            fault_path,
            served: 0,
            thread_scope: registry.thread_scope(),
        };
        w.send(0, BlockKind::Ready)?;
        Ok(w)
    }

    /// Serve commands until the supervisor closes the worker (or is gone).
    fn run(&mut self) -> Result<(), WorkerError> {
        if matches!(self.envs, WorkerEnvs::Shared(_)) {
            return self.run_concurrent(self.cfg.env_threads);
        }
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
        loop {
            let (seq, command, words) = self.next_command(&mut pacing)?;
            match command.serve() {
                None if command.op == Op::Close => return Ok(()),
                None => self.answer_calls(seq)?,
                Some(kind) => self.serve(seq, command, kind, words)?,
            }
        }
    }

    /// Wait for the next command; its payload is copied into `self.payload`. Returns its
    /// sequence number, the command and its payload's length in words.
    fn next_command(&mut self, pacing: &mut Pacing) -> Result<(u64, Command, usize), WorkerError> {
        let ppid = self.args.ppid;
        loop {
            let mut cmd = None;
            let (waiting, since) = (stamp(), Instant::now());
            hybrid_wait::<WorkerError>(self.ports.cmd_listener(), &pacing.now(), None, |call| {
                if call == WaitCall::Idle && nix::unistd::getppid().as_raw() != ppid {
                    return Err(WorkerError::ParentGone(ppid));
                }
                cmd = self.ports.try_recv_cmd()?;
                Ok(cmd.is_some())
            })?;
            self.stats
                .add(self.args.index, Counter::WaitNs, ns_since(waiting));
            pacing.last_gap = since.elapsed();
            let Some(cmd) = cmd else { continue };
            let h = *cmd.user_header();
            let command = Command::decode(h.kind)
                .map_err(|e| WorkerError::Msg(format!("command {}: {e}", h.seq)))?;
            pacing.pace = command.pace;
            let n = (h.len as usize).min(cmd.payload().len());
            let Some(dst) = self.payload.get_mut(..n) else {
                return Err(WorkerError::Msg(format!(
                    "command {} carries {n} words, more than a command to {} envs can",
                    h.seq, self.block_envs
                )));
            };
            dst.copy_from_slice(&cmd.payload()[..n]);
            return Ok((h.seq, command, n));
        }
    }

    /// Send an answer without data (`kind`) to command `seq` (its first word 0: it names no
    /// rows, see [`crate::wire::answer::rows_of`]).
    fn send(&mut self, seq: u64, kind: BlockKind) -> Result<(), WorkerError> {
        let mut block = self.ports.loan_block(sample_words(self.block_envs))?;
        *block.user_header_mut() = self.header(seq, kind);
        block.payload_mut()[0] = 0;
        self.publish(block)
    }

    /// Publish `block` and count it (see [`Worker::answers`]).
    fn publish(&mut self, block: rogue_gym_ipc::BlockSampleMut) -> Result<(), WorkerError> {
        let t = stamp();
        self.ports.send_block(block)?;
        self.answers += 1;
        self.stats
            .add(self.args.index, Counter::PublishNs, ns_since(t));
        Ok(())
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
    fn report(&mut self, seq: u64, f: &EnvFault) -> Result<(), WorkerError> {
        f.write(&self.fault_path).map_err(WorkerError::Msg)?;
        self.send(seq, BlockKind::Error)
    }

    /// [`Op::Call`]: env calls, off the hot path.
    fn answer_calls(&mut self, seq: u64) -> Result<(), WorkerError> {
        let me = (self.args.index, self.args.generation);
        match answer_calls(&self.id, me, &mut self.envs, self.first_env as u64) {
            Ok(()) => self.send(seq, BlockKind::Call),
            Err(f) => self.report(seq, &f),
        }
    }

    /// A reset or a step ([`Serve`]): every env it names writes its rows in the batch slot
    /// the command targets (a subset command: the slot its word names); one answer for them
    /// all.
    fn serve(
        &mut self,
        seq: u64,
        command: Command,
        kind: Serve,
        n: usize,
    ) -> Result<(), WorkerError> {
        // Words per env: one episode index per env for a reset, one action for a step; a
        // subset command adds one word per env (its slot).
        let epw = self.block_envs;
        let per_env = if kind == Serve::Step {
            self.action_words
        } else {
            1
        };
        let subset = command.subset;
        if n != epw * per_env + if subset { epw } else { 0 } {
            return Err(WorkerError::Msg(format!(
                "command {seq} carries {n} words for {epw} envs of {per_env} words (subset: \
                 {subset})"
            )));
        }
        let slots = self.cfg.batch_slots as u64;
        let target = u64::from(command.target);
        let (acts, only) = self.payload[..n].split_at(epw * per_env);
        let bad = if subset {
            only.iter().copied().find(|&w| w > slots)
        } else {
            (!(1..=slots).contains(&target)).then_some(target)
        };
        if let Some(t) = bad {
            return Err(WorkerError::Msg(format!(
                "command {seq}: observation target {t}, but the pool has {slots} slots"
            )));
        }
        if command.reload_seeds {
            self.seeds = read_config(&self.args.config)
                .map_err(WorkerError::Msg)?
                .seeds;
        }
        let me = self.args.index;
        self.served += 1;
        let misdeed = self.misdeed(self.served);
        let mut block = self.ports.loan_block(sample_words(epw))?;
        *block.user_header_mut() = self.header(seq, BlockKind::Data);
        let serving = stamp();
        let ctx = ServeCtx {
            seeds: &self.seeds,
            num_envs: self.cfg.num_envs as u64,
            autoreset: self.cfg.autoreset,
            action_bytes: self.action_bytes,
            n_info: self.n_info,
        };
        let first = self.first_env as u64;
        let extras = if kind == Serve::Step && command.action_extras {
            let me = (self.args.index, self.args.generation);
            take_action_extras(&self.id, me, &mut self.envs, first)
        } else {
            Ok(())
        };
        // One pass per slot the command writes (a whole command writes one).
        let mut built = AnswerBuilder::default();
        let mut apart: Vec<(u32, Vec<u8>)> = Vec::new();
        let mut served = extras.map(|()| 0);
        for slot in 1..=slots {
            let only = match subset {
                true if only.contains(&slot) => Some((only, slot)),
                false if slot == target => None,
                _ => continue,
            };
            // SAFETY: slot `slot - 1` lies in the batch buffer (`slot <= batch_slots`, checked
            // above), 64-byte aligned. This worker's envs own their rows of every area of it
            // during the command: the supervisor neither reads nor lends them out until the
            // command is answered, and no other worker writes them.
            let mut out = unsafe {
                let base = self
                    .batch
                    .as_ptr()
                    .add((slot as usize - 1) * self.slot_layout.bytes());
                BlockOut::in_slot(
                    self.slot_layout.rows(base),
                    self.first_env,
                    epw,
                    &mut self.scratch,
                )
            };
            out.answer = built;
            served = served.and_then(|c| {
                let more = self.envs.serve(kind, acts, per_env, only, &mut out, &ctx)?;
                Ok(c + more)
            });
            built = out.answer;
            apart.extend(out.take_apart());
            if served.is_err() {
                break;
            }
        }
        if self.streamed {
            // Streamed rows land before the answer that publishes them (an env that failed
            // midway included: its rows are written again before anyone reads them).
            streaming::fence();
        }
        let mut answer = built.finish(epw);
        // Info too long for its room goes beside the answer, in a private file named by it;
        // the supervisor takes it with the answer.
        let apart = match &served {
            Ok(_) if !apart.is_empty() => {
                let entries: Vec<(u32, &[u8])> =
                    apart.iter().map(|(j, b)| (*j, b.as_slice())).collect();
                let path = extra_apart_path(&self.id, me, self.args.generation, seq);
                calls::write(&path, &calls::encode(&entries)).map_err(|e| {
                    EnvFault::new(
                        first + u64::from(apart[0].0),
                        "extra info",
                        format!("cannot write the info that did not fit its room: {e}"),
                    )
                })
            }
            _ => Ok(()),
        };
        let served = served.and_then(|served| apart.map(|()| served));
        self.stats.add(me, Counter::EnvNs, ns_since(serving));
        self.stats.add(me, Counter::Commands, 1);
        let served = match served {
            Ok(served) => served,
            Err(f) => {
                drop(block);
                return self.report(seq, &f);
            }
        };
        self.envs.write_books(&self.books, seq, self.first_env);
        if let Some(m) = &misdeed {
            // At the first env the command served, in its slot.
            let j = if subset {
                only.iter().position(|&w| w != 0).unwrap_or(0)
            } else {
                0
            };
            let slot = if subset { only[j] } else { target };
            self.commit(m, seq, (slot as usize, j), &mut answer);
        }
        block.payload_mut()[..ANSWER_WORDS].copy_from_slice(&answer.encode());
        self.stats.add(me, Counter::EnvSteps, served as u64);
        self.publish(block)
    }
}
