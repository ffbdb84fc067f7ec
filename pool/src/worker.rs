//! The worker process: steps a block of envs and publishes their observations and records
//! through shared memory.
//!
//! Entry point: [`worker_main`], called by `rogue-gym worker ...`, by the e2e test binary and by
//! the Python extension (`python -m rogue_gym.worker ...`). Arguments (after the program and its
//! leading args): `--config <file> --index <k> --generation <g> --ppid <supervisor pid>`.

use std::path::PathBuf;
use std::time::Duration;

use rogue_gym_ipc::{
    BlockHeader, IpcError, PoolId, WaitCall, WaitPolicy, WorkerPorts, hybrid_wait,
};

use crate::config::AutoresetMode;
use crate::env::MAX_INFO;
use crate::registry::{Built, EnvRegistry};
use crate::stats::{Counter, StatsBuffer, ns_since, stamp};
use crate::wire::books::Books;
use crate::wire::layout::BlockLayout;
use crate::wire::slot_layout::SlotLayout;
use crate::wire::{
    BATCH_BUFFER, BLOCK_CALL, BLOCK_DATA, BLOCK_ERROR, BLOCK_READY, Command, EnvFault, Op,
    SLOT_ANSWER_WORDS, Serve, WorkerConfig, calls, env_fault_path, extra_apart_path, successor_go,
    successor_marker,
};

mod block;
mod env_state;
mod envs;
mod streaming;

use block::BlockHost;
use env_state::{BlockOut, EnvState, Rows, ServeCtx};
use envs::{WorkerEnvs, answer_calls, take_action_extras};

#[derive(Debug, thiserror::Error)]
enum WorkerError {
    #[error(transparent)]
    Ipc(#[from] IpcError),
    #[error("{0}")]
    Msg(String),
    #[error("the supervisor (pid {0}) is gone")]
    ParentGone(i32),
}

struct Args {
    config: PathBuf,
    index: usize,
    generation: u64,
    ppid: i32,
    /// A planned replacement ([`crate::wire::successor_marker`]): build the envs while the
    /// worker it replaces still serves, say so, then take over its ports once they are free.
    successor: bool,
}

fn parse_args(args: &[String]) -> Result<Args, String> {
    let mut config = None;
    let mut index = None;
    let mut generation = 0u64;
    let mut ppid = None;
    let mut successor = false;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut val = |name: &str| {
            it.next()
                .cloned()
                .ok_or_else(|| format!("{name} needs a value"))
        };
        match a.as_str() {
            "--config" => config = Some(PathBuf::from(val("--config")?)),
            "--index" => {
                index = Some(
                    val("--index")?
                        .parse()
                        .map_err(|e| format!("--index: {e}"))?,
                )
            }
            "--generation" => {
                generation = val("--generation")?
                    .parse()
                    .map_err(|e| format!("--generation: {e}"))?
            }
            "--ppid" => ppid = Some(val("--ppid")?.parse().map_err(|e| format!("--ppid: {e}"))?),
            "--successor" => successor = true,
            other => return Err(format!("unexpected argument {other:?}")),
        }
    }
    Ok(Args {
        config: config.ok_or("missing --config <file>")?,
        index: index.ok_or("missing --index <worker index>")?,
        generation,
        ppid: ppid.ok_or("missing --ppid <supervisor pid>")?,
        successor,
    })
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
                "rogue-gym worker: {e}\nusage: worker --config <file> --index <k> --generation <g> --ppid <pid>"
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
    if let Some(offset) = cfg.cpu_affinity
        && let Err(e) = pin_to_core(offset + a.index)
    {
        // Not fatal: the worker runs where the kernel puts it.
        eprintln!(
            "rogue-gym worker {}: cpu_affinity not applied: {e}",
            a.index
        );
    }
    match run(&a, &cfg, registry) {
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

/// Read the worker's config: a private file of this user in a private directory of this user
/// (the pool's, inside its verified runtime directory), so that no one else can have written
/// what the worker builds its envs from (hosted envs unpickle it).
/// Wait for the supervisor's word that the worker this successor replaces is gone
/// ([`successor_go`]), while the supervisor lives: a successor that is not needed is killed.
fn wait_for_go(id: &PoolId, a: &Args) -> Result<(), WorkerError> {
    let go = successor_go(id, a.index, a.generation);
    while !go.exists() {
        if nix::unistd::getppid().as_raw() != a.ppid {
            return Err(WorkerError::ParentGone(a.ppid));
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let _ = std::fs::remove_file(&go);
    Ok(())
}

/// Pin this process to the `n`-th core (wrapping around) of those it may run on.
fn pin_to_core(n: usize) -> Result<usize, nix::Error> {
    use nix::sched::{CpuSet, sched_getaffinity, sched_setaffinity};
    use nix::unistd::Pid;
    let allowed = sched_getaffinity(Pid::from_raw(0))?;
    let cores: Vec<usize> = (0..CpuSet::count())
        .filter(|&c| allowed.is_set(c).unwrap_or(false))
        .collect();
    let Some(&core) = cores.get(n % cores.len().max(1)) else {
        return Err(nix::Error::EINVAL);
    };
    let mut one = CpuSet::new();
    one.set(core)?;
    sched_setaffinity(Pid::from_raw(0), &one)?;
    Ok(core)
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

fn read_config(path: &std::path::Path) -> Result<WorkerConfig, String> {
    let dir = path.parent().unwrap_or(std::path::Path::new("/"));
    let meta = std::fs::symlink_metadata(dir)
        .map_err(|e| format!("cannot inspect {}: {e}", dir.display()))?;
    rogue_gym_ipc::private::check_private(dir, &meta, true).map_err(|e| e.to_string())?;
    let data = rogue_gym_ipc::private::read_private_file(path)
        .map_err(|e| format!("cannot read worker config: {e}"))?;
    serde_json::from_slice(&data).map_err(|e| format!("bad worker config: {e}"))
}

fn run(a: &Args, cfg: &WorkerConfig, registry: &EnvRegistry) -> Result<(), WorkerError> {
    if a.index >= cfg.num_workers || cfg.envs_of(a.index).is_empty() {
        return Err(WorkerError::Msg(format!(
            "worker index {} out of range (pool has {} workers for {} envs)",
            a.index, cfg.num_workers, cfg.num_envs
        )));
    }
    let envs = cfg.envs_of(a.index);
    let epw = envs.len();
    let id = PoolId::from_parts(&cfg.pool_name, &cfg.runtime_dir)?;
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
    let mut hosted = match built {
        Built::Envs(list) => WorkerEnvs::Each(
            list.into_iter()
                .zip(globals)
                .map(|(env, g)| EnvState::new(env, g))
                .collect(),
        ),
        Built::Block(block) => WorkerEnvs::Block(BlockHost::new(block, globals)),
    };
    let spec = match &hosted {
        WorkerEnvs::Each(slots) => slots[0].env.spec(),
        WorkerEnvs::Block(host) => host.spec(),
    };
    let n_info = spec.info_names.len().min(MAX_INFO);
    let aw = spec.action_words();
    let layout = BlockLayout {
        envs: epw,
        obs_bytes: spec.obs_bytes(),
        final_obs: cfg.autoreset == AutoresetMode::SameStep,
        extra_bytes: spec.extra_bytes,
    };
    let words = layout.words();
    let node = id.node(&format!("w{}g{}", a.index, a.generation))?;
    if a.successor {
        // The envs are built: the supervisor may now stop the worker this one replaces.
        rogue_gym_ipc::private::create_private_file(&successor_marker(&id, a.index, a.generation))?;
        wait_for_go(&id, a)?;
    }
    let ports = WorkerPorts::new(&node, a.index, words, &cfg.channel_settings())?;
    let policy = WaitPolicy {
        poll_budget: Duration::from_micros(cfg.poll_budget_us),
        block_slice: Duration::from_millis(cfg.block_slice_ms.max(1)),
        yield_cpu: cfg.poll_yield,
        sleep_first: Duration::ZERO,
    };
    let header = |seq, kind| BlockHeader {
        seq,
        generation: a.generation,
        worker: a.index as u32,
        kind,
        ready_ns: 0,
    };
    let ob = layout.obs_bytes;
    let slot_layout = SlotLayout {
        num_envs: cfg.num_envs,
        obs_bytes: ob,
        n_info,
        final_obs: layout.final_obs,
        extra_bytes: layout.extra_bytes,
    };
    let sb = slot_layout.bytes();
    let batch = rogue_gym_ipc::SharedBuffer::open(&id, BATCH_BUFFER, cfg.batch_slots * sb)?;
    let stats = StatsBuffer::open(&id, cfg.num_workers)?;
    let books = Books::open(&id, cfg.num_envs)?;
    let me = a.index;
    let first_env = envs.start;
    let mut ready = ports.loan_block(words)?;
    *ready.user_header_mut() = header(0, BLOCK_READY);
    ports.send_block(ready)?;

    let mut seeds = cfg.seeds.clone();
    let mut payload: Vec<u64> = vec![0; epw * aw + epw];
    // One env's extra info, and the block's infos that did not fit its room.
    let mut info: Vec<u8> = Vec::new();
    let mut apart: Vec<(u32, Vec<u8>)> = Vec::new();
    // Envs write their observation here first when the rows are streamed (see `streaming`).
    let streamed = streaming::wanted(cfg.streaming_stores, cfg.batch_slots * cfg.num_envs * ob);
    let mut stage: Vec<u8> = if streamed { vec![0; ob] } else { Vec::new() };
    // The last command asked to wait for the next one without polling (`block_at_once`).
    let blocking = WaitPolicy {
        poll_budget: Duration::ZERO,
        ..policy
    };
    let mut block_at_once = false;
    // How long the last command took to come after the answer before it.
    let mut last_gap = Duration::MAX;
    loop {
        let mut cmd = None;
        let waiting = stamp();
        let since = std::time::Instant::now();
        let now = if block_at_once {
            blocking
        } else {
            WaitPolicy {
                poll_budget: expected_poll(policy.poll_budget, last_gap),
                ..policy
            }
        };
        hybrid_wait::<WorkerError>(ports.cmd_listener(), &now, None, |call| {
            if call == WaitCall::Idle && nix::unistd::getppid().as_raw() != a.ppid {
                return Err(WorkerError::ParentGone(a.ppid));
            }
            cmd = ports.try_recv_cmd()?;
            Ok(cmd.is_some())
        })?;
        stats.add(me, Counter::WaitNs, ns_since(waiting));
        last_gap = since.elapsed();
        let Some(cmd) = cmd else { continue };
        let h = *cmd.user_header();
        let n = (h.len as usize).min(cmd.payload().len());
        let command = Command::decode(h.kind)
            .map_err(|e| WorkerError::Msg(format!("command {}: {e}", h.seq)))?;
        block_at_once = command.block_at_once;
        if command.op == Op::Close {
            return Ok(());
        }
        let Some(kind) = command.serve() else {
            // Op::Call: env calls, off the hot path.
            drop(cmd);
            let kind =
                match answer_calls(&id, (a.index, a.generation), &mut hosted, first_env as u64) {
                    Ok(()) => BLOCK_CALL,
                    Err(f) => {
                        f.write(&fault_path).map_err(WorkerError::Msg)?;
                        BLOCK_ERROR
                    }
                };
            let mut reply = ports.loan_block(words)?;
            *reply.user_header_mut() = header(h.seq, kind);
            ports.send_block(reply)?;
            continue;
        };
        // Words per env: one episode index per env for a reset, one action for a step; a
        // subset step adds one word per env (whether it steps).
        let per_env = if kind == Serve::Step { aw } else { 1 };
        let subset = kind == Serve::Step && command.subset;
        let want = epw * per_env + if subset { epw } else { 0 };
        if n != want {
            return Err(WorkerError::Msg(format!(
                "command {} carries {n} words for {epw} envs of {per_env} words (subset: {subset})",
                h.seq
            )));
        }
        payload[..n].copy_from_slice(&cmd.payload()[..n]);
        drop(cmd);
        let (acts, only) = payload[..n].split_at(epw * per_env);
        let only = subset.then_some(only);

        let target = command.target as usize;
        if command.reload_seeds {
            seeds = read_config(&a.config).map_err(WorkerError::Msg)?.seeds;
        }
        let ctx = ServeCtx {
            seeds: &seeds,
            num_envs: cfg.num_envs as u64,
            autoreset: cfg.autoreset,
            num_actions: spec.num_actions,
            action_bytes: spec.action_bytes,
            n_info,
        };
        if target > cfg.batch_slots {
            return Err(WorkerError::Msg(format!("bad observation target {target}")));
        }
        let mut block = ports.loan_block(words)?;
        *block.user_header_mut() = header(h.seq, BLOCK_DATA);
        let areas = layout.split_mut(block.payload_mut());
        apart.clear();
        let mut out = if target == 0 {
            BlockOut {
                records: Rows::Block(areas.records),
                summary: Default::default(),
                obs: areas.obs,
                final_obs: areas.final_obs,
                extra: areas.extra,
                obs_bytes: ob,
                final_bytes: if layout.final_obs { ob } else { 0 },
                extra_bytes: layout.extra_bytes,
                info: &mut info,
                apart: &mut apart,
                stage: &mut stage,
            }
        } else {
            let rows = first_env..first_env + epw;
            // SAFETY: the shared batch buffer holds `cfg.batch_slots` slots of `sb` bytes, so
            // slot `target - 1` is inside it. This worker's envs own rows `rows` of every area
            // of that slot: the supervisor neither reads nor lends them out until this command
            // is answered, and no other worker writes them.
            let (writer, obs, fin, extra) = unsafe {
                let w = slot_layout.writer(batch.as_ptr().add((target - 1) * sb));
                let (o, f, x) = (
                    w.obs_rows(rows.clone()),
                    w.final_rows(rows.clone()),
                    w.extra_rows(rows),
                );
                (w, o, f, x)
            };
            BlockOut {
                records: Rows::Slot {
                    writer: Box::new(writer),
                    first: first_env,
                },
                summary: Default::default(),
                obs,
                final_obs: fin,
                extra,
                obs_bytes: ob,
                final_bytes: if layout.final_obs { ob } else { 0 },
                extra_bytes: layout.extra_bytes,
                info: &mut info,
                apart: &mut apart,
                stage: &mut stage,
            }
        };
        let serving = stamp();
        let extras = if kind == Serve::Step && command.action_extras {
            take_action_extras(&id, (a.index, a.generation), &mut hosted, first_env as u64)
        } else {
            Ok(())
        };
        let (mut failed, served) =
            match extras.and_then(|()| hosted.serve(kind, acts, per_env, only, &mut out, &ctx)) {
                Ok(served) => (None, served),
                Err(f) => (Some(f), 0),
            };
        if streamed {
            // Streamed rows land before the answer that publishes them (an env that failed
            // midway included: its rows are written again before anyone reads them).
            streaming::fence();
        }
        if failed.is_none() {
            hosted.write_books(&books, h.seq, first_env);
        }
        let answer = out.summary.words(epw);
        if target != 0 {
            block.payload_mut()[..SLOT_ANSWER_WORDS].copy_from_slice(&answer);
        }
        stats.add(me, Counter::EnvNs, ns_since(serving));
        stats.add(me, Counter::EnvSteps, served as u64);
        stats.add(me, Counter::Commands, 1);
        let publishing = stamp();
        if failed.is_none() && !apart.is_empty() {
            // Info too long for the block's room goes beside it, in a private file named by
            // the block; the supervisor takes it with the block.
            let entries: Vec<(u32, &[u8])> =
                apart.iter().map(|(j, b)| (*j, b.as_slice())).collect();
            let path = extra_apart_path(&id, a.index, a.generation, h.seq);
            if let Err(e) = calls::write(&path, &calls::encode(&entries)) {
                failed = Some(EnvFault::new(
                    first_env as u64 + u64::from(apart[0].0),
                    "extra info",
                    format!("cannot write the info that did not fit the block: {e}"),
                ));
            }
        }
        if let Some(f) = failed {
            // An env failed: report it (the supervisor raises it to the caller and requires a
            // reset) and keep serving; the worker itself is fine.
            drop(block);
            f.write(&fault_path).map_err(WorkerError::Msg)?;
            let mut report = ports.loan_block(words)?;
            *report.user_header_mut() = header(h.seq, BLOCK_ERROR);
            ports.send_block(report)?;
            continue;
        }
        ports.send_block(block)?;
        stats.add(me, Counter::PublishNs, ns_since(publishing));
    }
}
