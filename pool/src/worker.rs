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
use crate::env::{Env, MAX_INFO};
use crate::registry::{Built, EnvRegistry};
use crate::seeds::SeedSchedule;
use crate::wire::layout::{
    BlockLayout, EnvRecord, FLAG_EXTRA_APART, FLAG_FINAL_OBS, FLAG_TERMINATED, FLAG_TRUNCATED,
    write_record_words,
};
use crate::wire::{
    BATCH_BUFFER, BLOCK_CALL, BLOCK_DATA, BLOCK_ERROR, BLOCK_READY, CMD_CALL, CMD_CLOSE, CMD_RESET,
    CMD_STEP, EnvFault, KEEP_EPISODE, RELOAD_SEEDS, TARGET_SHIFT, WorkerConfig, calls,
    env_fault_path, extra_apart_path, slot_bytes,
};

mod block;
use block::BlockHost;

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
}

fn parse_args(args: &[String]) -> Result<Args, String> {
    let mut config = None;
    let mut index = None;
    let mut generation = 0u64;
    let mut ppid = None;
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
            other => return Err(format!("unexpected argument {other:?}")),
        }
    }
    Ok(Args {
        config: config.ok_or("missing --config <file>")?,
        index: index.ok_or("missing --index <worker index>")?,
        generation,
        ppid: ppid.ok_or("missing --ppid <supervisor pid>")?,
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
fn read_config(path: &std::path::Path) -> Result<WorkerConfig, String> {
    let dir = path.parent().unwrap_or(std::path::Path::new("/"));
    let meta = std::fs::symlink_metadata(dir)
        .map_err(|e| format!("cannot inspect {}: {e}", dir.display()))?;
    rogue_gym_ipc::private::check_private(dir, &meta, true).map_err(|e| e.to_string())?;
    let data = rogue_gym_ipc::private::read_private_file(path)
        .map_err(|e| format!("cannot read worker config: {e}"))?;
    serde_json::from_slice(&data).map_err(|e| format!("bad worker config: {e}"))
}

/// One env of a worker with its episode bookkeeping (`E = ()` for the envs of an
/// [`crate::EnvBlock`], which owns them).
pub(crate) struct Slot<E = Box<dyn Env>> {
    pub(crate) env: E,
    /// Global env id.
    pub(crate) global: u64,
    pub(crate) episode: u64,
    pub(crate) seed: u64,
    pub(crate) ret: f64,
    pub(crate) len: u32,
    pub(crate) needs_reset: bool,
}

impl<E> Slot<E> {
    pub(crate) fn new(env: E, global: u64) -> Self {
        Slot {
            env,
            global,
            episode: 0,
            seed: 0,
            ret: 0.0,
            len: 0,
            needs_reset: true,
        }
    }

    /// Begin the episode `self.episode` (its seed from the schedule; return and length 0).
    pub(crate) fn begin_episode(&mut self, ctx: &SlotCtx) {
        self.seed = ctx.seeds.seed(self.global, self.episode, ctx.num_envs);
        self.ret = 0.0;
        self.len = 0;
        self.needs_reset = false;
    }

    /// The record's episode bookkeeping.
    pub(crate) fn stamp(&self, rec: &mut EnvRecord) {
        rec.episode = self.episode;
        rec.seed = self.seed;
        rec.episode_return = self.ret;
        rec.episode_length = self.len;
    }

    /// Fail if `value` is an action index out of range (envs of raw action bytes check their
    /// actions themselves).
    pub(crate) fn check_action(&self, value: u64, ctx: &SlotCtx) -> Result<(), EnvFault> {
        if ctx.action_bytes > 0 || value < ctx.num_actions as u64 {
            return Ok(());
        }
        let msg = format!(
            "action {value} is out of range; valid actions are 0 to {} (range({}))",
            ctx.num_actions.saturating_sub(1),
            ctx.num_actions
        );
        Err(fault(self, "step".into(), msg))
    }

    /// The context of a failed step of this env.
    pub(crate) fn step_context(&self) -> String {
        format!(
            "step (episode {}, seed {}, step {})",
            self.episode, self.seed, self.len
        )
    }
}

/// What [`apply`] needs besides the slot.
pub(crate) struct SlotCtx<'a> {
    pub(crate) seeds: &'a SeedSchedule,
    pub(crate) num_envs: u64,
    pub(crate) autoreset: AutoresetMode,
    pub(crate) num_actions: usize,
    /// `EnvSpec::action_bytes` (0: action indices).
    pub(crate) action_bytes: usize,
    pub(crate) n_info: usize,
}

/// Where one env writes its answer to a command (parts of the block being filled).
pub(crate) struct EnvOut<'a> {
    pub(crate) obs: &'a mut [u8],
    /// SAME_STEP final observation (empty in NEXT_STEP mode).
    pub(crate) fin: &'a mut [u8],
    /// Extra-info room (`EnvSpec::extra_bytes`).
    pub(crate) extra: &'a mut [u8],
    /// The env's extra info, whole; when it does not fit `extra`, the record is flagged
    /// [`FLAG_EXTRA_APART`] and the caller sends these bytes apart.
    pub(crate) info: &'a mut Vec<u8>,
}

pub(crate) fn fault<E>(s: &Slot<E>, context: String, message: impl std::fmt::Display) -> EnvFault {
    EnvFault {
        env: s.global,
        context,
        message: message.to_string(),
    }
}

fn do_reset(s: &mut Slot, obs: &mut [u8], ctx: &SlotCtx) -> Result<(), EnvFault> {
    s.begin_episode(ctx);
    s.env.reset_episode(s.seed, s.episode, obs).map_err(|e| {
        fault(
            s,
            format!("reset (episode {}, seed {})", s.episode, s.seed),
            e,
        )
    })
}

/// Apply one command to one env: `CMD_RESET` (`words[0]` = episode index) or `CMD_STEP`
/// (`words` = the action: an index, or `action_bytes` raw bytes), with autoreset. Writes the
/// observation, the final observation (SAME_STEP, on an episode end) and the extra info into
/// `out`. Returns the env's record.
pub(crate) fn apply(
    s: &mut Slot,
    kind: u32,
    words: &[u64],
    out: EnvOut<'_>,
    ctx: &SlotCtx,
) -> Result<EnvRecord, EnvFault> {
    let EnvOut {
        obs,
        fin,
        extra,
        info,
    } = out;
    let value = words.first().copied().unwrap_or(0);
    let mut rec = EnvRecord::default();
    match kind {
        CMD_RESET if value == KEEP_EPISODE => {
            // Partial reset, env not selected: no state change, same observation again.
            s.env.observe(obs).map_err(|e| {
                let c = format!(
                    "a partial reset (episode {}, seed {}): cannot keep it",
                    s.episode, s.seed
                );
                fault(s, c, e)
            })?;
        }
        CMD_RESET => {
            s.episode = value;
            do_reset(s, obs, ctx)?;
        }
        CMD_STEP if s.needs_reset => {
            // NEXT_STEP: this step only resets; the action is ignored.
            s.episode += 1;
            do_reset(s, obs, ctx)?;
        }
        CMD_STEP => {
            s.check_action(value, ctx)?;
            let result = if ctx.action_bytes > 0 {
                let bytes = rogue_gym_ipc::words_as_bytes(words);
                s.env
                    .step_bytes(&bytes[..ctx.action_bytes.min(bytes.len())], obs)
            } else {
                s.env.step(value as usize, obs)
            };
            let out = result.map_err(|e| fault(s, s.step_context(), e))?;
            s.ret += out.reward;
            s.len += 1;
            rec.reward = out.reward;
            rec.flags = (u32::from(out.terminated) * FLAG_TERMINATED)
                | (u32::from(out.truncated) * FLAG_TRUNCATED);
        }
        k => {
            return Err(fault(
                s,
                "a command".into(),
                format!("unknown command kind {k}"),
            ));
        }
    }
    s.stamp(&mut rec);
    s.env.info(&mut rec.info[..ctx.n_info]);
    if rec.flags & (FLAG_TERMINATED | FLAG_TRUNCATED) != 0 {
        match ctx.autoreset {
            AutoresetMode::NextStep => s.needs_reset = true,
            AutoresetMode::SameStep => {
                if fin.len() == obs.len() {
                    fin.copy_from_slice(obs);
                    rec.flags |= FLAG_FINAL_OBS;
                }
                s.episode += 1;
                do_reset(s, obs, ctx)?;
            }
        }
    }
    if !extra.is_empty() {
        // The env has extra info (`EnvSpec::extra_bytes` > 0, so it has room).
        info.clear();
        s.env
            .extra_info(info)
            .map_err(|e| fault(s, "extra info".into(), e))?;
        place_extra(&mut rec, extra, info).map_err(|e| fault(s, "extra info".into(), e))?;
    }
    Ok(rec)
}

/// Put an env's extra info `info` in its room `extra`, or flag the record
/// [`FLAG_EXTRA_APART`] when it does not fit (the worker then sends it beside the block).
pub(crate) fn place_extra(
    rec: &mut EnvRecord,
    extra: &mut [u8],
    info: &[u8],
) -> Result<(), String> {
    let n = info.len();
    rec.extra_len = u32::try_from(n).map_err(|_| format!("{n} bytes of extra info"))?;
    match extra.get_mut(..n) {
        Some(room) => room.copy_from_slice(info),
        None => rec.flags |= FLAG_EXTRA_APART,
    }
    Ok(())
}

/// A worker's envs: one [`Env`] each, or one [`crate::EnvBlock`] for them all.
enum Hosted {
    Each(Vec<Slot>),
    Block(BlockHost),
}

impl Hosted {
    fn len(&self) -> usize {
        match self {
            Hosted::Each(slots) => slots.len(),
            Hosted::Block(host) => host.len(),
        }
    }

    /// Answer one command (`kind`, with `per_env` payload words per env) into `out`.
    fn serve(
        &mut self,
        kind: u32,
        payload: &[u64],
        per_env: usize,
        out: &mut BlockOut<'_>,
        ctx: &SlotCtx,
    ) -> Result<(), EnvFault> {
        let slots = match self {
            Hosted::Block(host) => return host.serve(kind, payload, out, ctx),
            Hosted::Each(slots) => slots,
        };
        for (j, s) in slots.iter_mut().enumerate() {
            let rec = apply(
                s,
                kind,
                &payload[j * per_env..(j + 1) * per_env],
                out.env(j),
                ctx,
            )?;
            out.finish(j, &rec);
        }
        Ok(())
    }
}

/// Where one command's answers go: the parts of the worker's block being filled.
pub(crate) struct BlockOut<'a> {
    pub(crate) records: &'a mut [u64],
    pub(crate) obs: &'a mut [u8],
    pub(crate) final_obs: &'a mut [u8],
    pub(crate) extra: &'a mut [u8],
    pub(crate) obs_bytes: usize,
    pub(crate) final_bytes: usize,
    pub(crate) extra_bytes: usize,
    /// One env's extra info (a buffer reused from env to env).
    pub(crate) info: &'a mut Vec<u8>,
    /// The envs whose info did not fit their room, with that info.
    pub(crate) apart: &'a mut Vec<(u32, Vec<u8>)>,
}

impl BlockOut<'_> {
    /// Env `j`'s parts.
    fn env(&mut self, j: usize) -> EnvOut<'_> {
        let (ob, fb, xb) = (self.obs_bytes, self.final_bytes, self.extra_bytes);
        EnvOut {
            obs: &mut self.obs[j * ob..(j + 1) * ob],
            fin: &mut self.final_obs[j * fb..(j + 1) * fb],
            extra: &mut self.extra[j * xb..(j + 1) * xb],
            info: &mut *self.info,
        }
    }

    /// Write env `j`'s record; keep its info apart if the record says it did not fit.
    pub(crate) fn finish(&mut self, j: usize, rec: &EnvRecord) {
        write_record_words(self.records, j, rec);
        if rec.extra_apart() {
            self.apart.push((j as u32, std::mem::take(self.info)));
        }
    }
}

/// Answer the call requests of the worker's call file ([`calls`]), env by env.
fn answer_calls(id: &PoolId, a: &Args, hosted: &mut Hosted, first: u64) -> Result<(), EnvFault> {
    let fail = |env: u64, message: String| EnvFault {
        env,
        context: "a call".into(),
        message,
    };
    let requests =
        calls::take(&calls::request_path(id, a.index, a.generation)).map_err(|e| fail(first, e))?;
    let mut replies = Vec::with_capacity(requests.len());
    for (row, request) in &requests {
        let j = *row as usize;
        if j >= hosted.len() {
            return Err(fail(
                first,
                format!("call for row {row}, outside the block"),
            ));
        }
        let reply = match hosted {
            Hosted::Each(slots) => slots[j].env.call(request),
            Hosted::Block(host) => host.call(j, request),
        };
        replies.push((
            *row,
            reply.map_err(|e| fail(first + j as u64, e.to_string()))?,
        ));
    }
    let entries: Vec<(u32, &[u8])> = replies.iter().map(|(r, b)| (*r, b.as_slice())).collect();
    calls::write(
        &calls::reply_path(id, a.index, a.generation),
        &calls::encode(&entries),
    )
    .map_err(|e| fail(first, e))
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
            let fault = EnvFault {
                env: building,
                context: "construction".into(),
                message: e.to_string(),
            };
            let _ = fault.write(&fault_path);
            WorkerError::Msg(format!("cannot build env {building}: {e}"))
        })?;
    let mut hosted = match built {
        Built::Envs(list) => Hosted::Each(
            list.into_iter()
                .zip(globals)
                .map(|(env, g)| Slot::new(env, g))
                .collect(),
        ),
        Built::Block(block) => Hosted::Block(BlockHost::new(block, globals)),
    };
    let spec = match &hosted {
        Hosted::Each(slots) => slots[0].env.spec(),
        Hosted::Block(host) => host.spec(),
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
    let ports = WorkerPorts::new(&node, a.index, words, &cfg.channel_settings())?;
    let policy = WaitPolicy {
        poll_budget: Duration::from_micros(cfg.poll_budget_us),
        block_slice: Duration::from_millis(cfg.block_slice_ms.max(1)),
        yield_cpu: cfg.poll_yield,
    };
    let header = |seq, kind| BlockHeader {
        seq,
        generation: a.generation,
        worker: a.index as u32,
        kind,
    };
    let ob = layout.obs_bytes;
    let sb = slot_bytes(cfg.num_envs, ob);
    let batch = rogue_gym_ipc::SharedBuffer::open(&id, BATCH_BUFFER, cfg.batch_slots * sb)?;
    let first_env = envs.start;
    let mut ready = ports.loan_block(words)?;
    *ready.user_header_mut() = header(0, BLOCK_READY);
    ports.send_block(ready)?;

    let mut seeds = cfg.seeds.clone();
    let mut payload: Vec<u64> = vec![0; epw * aw];
    // One env's extra info, and the block's infos that did not fit its room.
    let mut info: Vec<u8> = Vec::new();
    let mut apart: Vec<(u32, Vec<u8>)> = Vec::new();
    loop {
        let mut cmd = None;
        hybrid_wait::<WorkerError>(ports.cmd_listener(), &policy, None, |call| {
            if call == WaitCall::Idle && nix::unistd::getppid().as_raw() != a.ppid {
                return Err(WorkerError::ParentGone(a.ppid));
            }
            cmd = ports.try_recv_cmd()?;
            Ok(cmd.is_some())
        })?;
        let Some(cmd) = cmd else { continue };
        let h = *cmd.user_header();
        let n = (h.len as usize).min(cmd.payload().len());
        if h.kind == CMD_CLOSE {
            return Ok(());
        }
        let kind = h.kind & ((1 << TARGET_SHIFT) - 1);
        if kind == CMD_CALL {
            drop(cmd);
            let kind = match answer_calls(&id, a, &mut hosted, first_env as u64) {
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
        }
        // Words per env: one episode index per env for a reset, one action for a step.
        let per_env = if kind == CMD_STEP { aw } else { 1 };
        if n != epw * per_env {
            return Err(WorkerError::Msg(format!(
                "command {} carries {n} words for {epw} envs of {per_env} words",
                h.seq
            )));
        }
        payload[..n].copy_from_slice(&cmd.payload()[..n]);
        drop(cmd);

        let target = ((h.kind & (RELOAD_SEEDS - 1)) >> TARGET_SHIFT) as usize;
        if h.kind & RELOAD_SEEDS != 0 {
            seeds = read_config(&a.config).map_err(WorkerError::Msg)?.seeds;
        }
        let ctx = SlotCtx {
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
        let obs_area: &mut [u8] = if target == 0 {
            areas.obs
        } else {
            // SAFETY: the shared batch buffer holds `cfg.batch_slots` slots of `sb` bytes; this
            // worker's envs occupy bytes [first_env*ob, (first_env+epw)*ob) of slot
            // `target - 1`, which the supervisor neither reads nor lends out until this
            // command is answered, and no other worker writes them.
            unsafe {
                std::slice::from_raw_parts_mut(
                    batch.as_ptr().add((target - 1) * sb + first_env * ob),
                    epw * ob,
                )
            }
        };
        apart.clear();
        let mut out = BlockOut {
            records: areas.records,
            obs: obs_area,
            final_obs: areas.final_obs,
            extra: areas.extra,
            obs_bytes: ob,
            final_bytes: if layout.final_obs { ob } else { 0 },
            extra_bytes: layout.extra_bytes,
            info: &mut info,
            apart: &mut apart,
        };
        let mut failed = hosted
            .serve(kind, &payload[..n], per_env, &mut out, &ctx)
            .err();
        if failed.is_none() && !apart.is_empty() {
            // Info too long for the block's room goes beside it, in a private file named by
            // the block; the supervisor takes it with the block.
            let entries: Vec<(u32, &[u8])> =
                apart.iter().map(|(j, b)| (*j, b.as_slice())).collect();
            let path = extra_apart_path(&id, a.index, a.generation, h.seq);
            if let Err(e) = calls::write(&path, &calls::encode(&entries)) {
                failed = Some(EnvFault {
                    env: first_env as u64 + u64::from(apart[0].0),
                    context: "extra info".into(),
                    message: format!("cannot write the info that did not fit the block: {e}"),
                });
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
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinds::test_env::TestEnv;

    fn slot() -> Slot {
        let env =
            TestEnv::from_json(&serde_json::json!({"obs_shape": [4], "max_steps": 3})).unwrap();
        Slot::new(Box::new(env), 5)
    }

    fn go(
        s: &mut Slot,
        kind: u32,
        value: u64,
        obs: &mut [u8],
        fin: &mut [u8],
        c: &SlotCtx,
    ) -> Result<EnvRecord, EnvFault> {
        let extra: &mut [u8] = &mut [];
        let info = &mut Vec::new();
        apply(
            s,
            kind,
            &[value],
            EnvOut {
                obs,
                fin,
                extra,
                info,
            },
            c,
        )
    }

    fn ctx(seeds: &SeedSchedule, autoreset: AutoresetMode) -> SlotCtx<'_> {
        SlotCtx {
            seeds,
            num_envs: 8,
            autoreset,
            num_actions: 5,
            action_bytes: 0,
            n_info: 2,
        }
    }

    #[test]
    fn next_step_autoreset_ignores_action_and_keeps_last_reward() {
        let seeds = SeedSchedule::from_base(1);
        let c = ctx(&seeds, AutoresetMode::NextStep);
        let mut s = slot();
        let (mut obs, mut fin) = ([0u8; 4], [0u8; 0]);
        let r = go(&mut s, CMD_RESET, 0, &mut obs, &mut fin, &c).unwrap();
        assert_eq!((r.episode, r.seed, r.flags), (0, seeds.seed(5, 0, 8), 0));
        let mut total = 0.0;
        for t in 1..=3 {
            let r = go(&mut s, CMD_STEP, 1, &mut obs, &mut fin, &c).unwrap();
            total += r.reward;
            assert_eq!(r.episode_length, t);
            if r.terminated() {
                break;
            }
            assert_eq!(r.truncated(), t == 3, "max_steps 3 truncates at step 3");
        }
        // The episode ended: its last reward was reported; the next step only resets.
        assert_eq!(s.ret, total);
        let r = go(&mut s, CMD_STEP, 4, &mut obs, &mut fin, &c).unwrap();
        assert_eq!(r.reward, 0.0);
        assert!(!r.terminated() && !r.truncated());
        assert_eq!(
            (r.episode, r.seed, r.episode_length),
            (1, seeds.seed(5, 1, 8), 0)
        );
        let mut fresh = [0u8; 4];
        let mut e = TestEnv::from_json(&serde_json::json!({"obs_shape": [4]})).unwrap();
        e.reset(seeds.seed(5, 1, 8), &mut fresh).unwrap();
        assert_eq!(obs, fresh, "the reset obs is returned");
    }

    #[test]
    fn same_step_autoreset_returns_reset_obs_and_final_obs() {
        let seeds = SeedSchedule::from_base(1);
        let c = ctx(&seeds, AutoresetMode::SameStep);
        let mut s = slot();
        let (mut obs, mut fin) = ([0u8; 4], [0u8; 4]);
        go(&mut s, CMD_RESET, 0, &mut obs, &mut fin, &c).unwrap();
        // Replay the same episode on a bare env to know the final obs.
        let mut bare =
            TestEnv::from_json(&serde_json::json!({"obs_shape": [4], "max_steps": 3})).unwrap();
        let mut bobs = [0u8; 4];
        bare.reset(seeds.seed(5, 0, 8), &mut bobs).unwrap();
        loop {
            let o = bare.step(2, &mut bobs).unwrap();
            let r = go(&mut s, CMD_STEP, 2, &mut obs, &mut fin, &c).unwrap();
            assert_eq!(r.reward, o.reward, "the final reward is kept");
            if o.terminated || o.truncated {
                assert_eq!((r.terminated(), r.truncated()), (o.terminated, o.truncated));
                assert!(r.has_final_obs());
                assert_eq!(fin, bobs, "final obs kept separately");
                assert_eq!(r.episode, 0, "the record describes the finished episode");
                bare.reset(seeds.seed(5, 1, 8), &mut bobs).unwrap();
                assert_eq!(obs, bobs, "obs is the next episode's first");
                assert_eq!(s.episode, 1);
                break;
            }
            assert_eq!(obs, bobs);
        }
        // The next step acts normally in the new episode.
        let r = go(&mut s, CMD_STEP, 0, &mut obs, &mut fin, &c).unwrap();
        assert_eq!((r.episode, r.episode_length), (1, 1));
    }

    #[test]
    fn bad_action_is_an_error_not_a_panic() {
        let seeds = SeedSchedule::from_base(1);
        let c = ctx(&seeds, AutoresetMode::NextStep);
        let mut s = slot();
        let (mut obs, mut fin) = ([0u8; 4], [0u8; 0]);
        go(&mut s, CMD_RESET, 0, &mut obs, &mut fin, &c).unwrap();
        let e = go(&mut s, CMD_STEP, 99, &mut obs, &mut fin, &c).unwrap_err();
        assert_eq!(e.env, 5);
        assert!(e.message.contains("action 99"), "{}", e.message);
    }
}
