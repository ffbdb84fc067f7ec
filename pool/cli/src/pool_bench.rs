//! `rogue-gym pool-bench`: env steps/s and batch latency of the pool, and the raw
//! single-process loop over the same envs measured in the same run.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use rogue_gym_pool::{
    BatchOutput, Env, EnvRegistry, Pool, PoolConfig, SeedSchedule, WaitPolicy, WorkerCommand,
};
use serde_json::{Value, json};

/// Sync (lockstep) or async (EnvPool-style send/recv) mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Mode {
    /// Sync `step` over all envs, the rows copied out (`Pool::read_rows`).
    Sync,
    /// `send`/`recv` with a batch of `--batch-size` envs.
    Async,
    /// Sync `step`: workers write into the pool's shared batch slots, read in place (no copy).
    Shared,
}

/// Options of `pool-bench`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Number of envs.
    #[arg(long, default_value_t = 64)]
    envs: usize,
    /// Number of worker processes.
    #[arg(long, default_value_t = 2)]
    workers: usize,
    /// Pool mode.
    #[arg(long, value_enum, default_value_t = Mode::Sync)]
    mode: Mode,
    /// Game config JSON file (rogue env); default: the paper's config.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Batches to time (each `--envs` env steps in sync mode).
    #[arg(long, default_value_t = 2000)]
    steps: u64,
    /// Env: `rogue`, `test`, or a full JSON env spec.
    #[arg(long, default_value = "rogue")]
    env: String,
    /// Async batch size (a multiple of envs/workers); default: half the envs.
    #[arg(long)]
    batch_size: Option<usize>,
    /// Episode step limit.
    #[arg(long, default_value_t = 500)]
    max_steps: u32,
    /// Supervisor yield-poll budget, µs.
    #[arg(long, default_value_t = 50)]
    poll_us: u64,
    /// Worker yield-poll budget, µs.
    #[arg(long, default_value_t = 50)]
    worker_poll_us: u64,
    /// Supervisor polls by spinning instead of yielding.
    #[arg(long)]
    spin: bool,
    /// Workers poll by spinning instead of yielding.
    #[arg(long)]
    worker_spin: bool,
    /// Base seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Raw and pool run alternately in this many chunks (fair under changing machine load).
    #[arg(long, default_value_t = 10)]
    rounds: u64,
}

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
}

fn env_spec(a: &Args) -> Result<Value, String> {
    match a.env.as_str() {
        "rogue" => {
            let config = match &a.config {
                Some(p) => {
                    let s = std::fs::read_to_string(p)
                        .map_err(|e| format!("cannot read {}: {e}", p.display()))?;
                    serde_json::from_str::<Value>(&s)
                        .map_err(|e| format!("{} is not JSON: {e}", p.display()))?
                }
                None => Value::Null,
            };
            Ok(json!({"kind": "rogue", "config": config, "max_steps": a.max_steps}))
        }
        "test" => Ok(json!({"kind": "test", "obs_shape": [17, 16, 32], "max_steps": a.max_steps})),
        s if s.trim_start().starts_with('{') => {
            serde_json::from_str(s).map_err(|e| format!("--env is not valid JSON: {e}"))
        }
        s => Err(format!(
            "unknown --env {s:?}: use rogue, test, or a JSON env spec"
        )),
    }
}

fn pct(v: &mut [Duration], p: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort();
    let i = ((v.len() - 1) as f64 * p).round() as usize;
    v[i].as_secs_f64() * 1e6
}

/// The raw loop: the same envs stepped in this process, one after another, with autoreset.
struct Raw {
    envs: Vec<Box<dyn Env>>,
    words: Vec<u64>,
    episode: Vec<u64>,
    seeds: SeedSchedule,
    rng: Rng,
    ob: usize,
    na: u64,
}

impl Raw {
    fn new(spec: &Value, a: &Args, reg: &EnvRegistry) -> Result<Raw, String> {
        let mut envs = (0..a.envs)
            .map(|i| reg.make(spec, i as u64))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| e.to_string())?;
        let s = envs[0].spec();
        let ob = s.obs_bytes();
        let seeds = SeedSchedule::from_base(a.seed);
        // f32 observations need 4-byte alignment: allocate as u64 words.
        let mut words = vec![0u64; (a.envs * ob).div_ceil(8)];
        let buf = rogue_gym_ipc::words_as_bytes_mut(&mut words);
        for (i, e) in envs.iter_mut().enumerate() {
            e.reset(
                seeds.seed(i as u64, 0, a.envs as u64),
                &mut buf[i * ob..(i + 1) * ob],
            )
            .map_err(|e| e.to_string())?;
        }
        Ok(Raw {
            envs,
            words,
            episode: vec![0; a.envs],
            seeds,
            rng: Rng(0x9E37_79B9_7F4A_7C15 ^ a.seed),
            ob,
            na: s.num_actions as u64,
        })
    }

    /// Step every env `batches` times; returns the time taken.
    fn run(&mut self, batches: u64) -> Result<Duration, String> {
        let n = self.envs.len() as u64;
        let ob = self.ob;
        let buf = rogue_gym_ipc::words_as_bytes_mut(&mut self.words);
        let t0 = Instant::now();
        for _ in 0..batches {
            for (i, e) in self.envs.iter_mut().enumerate() {
                let obs = &mut buf[i * ob..(i + 1) * ob];
                let o = e
                    .step((self.rng.next() % self.na) as usize, obs)
                    .map_err(|e| e.to_string())?;
                if o.terminated || o.truncated {
                    self.episode[i] += 1;
                    let seed = self.seeds.seed(i as u64, self.episode[i], n);
                    e.reset(seed, obs).map_err(|e| e.to_string())?;
                }
            }
        }
        Ok(t0.elapsed())
    }
}

/// The pool side of the benchmark.
struct PoolRun {
    pool: Pool,
    mode: Mode,
    obs: Vec<u8>,
    out: BatchOutput,
    actions: Vec<i64>,
    rng: Rng,
    lat: Vec<Duration>,
    na: u64,
}

impl PoolRun {
    fn new(spec: &Value, a: &Args, reg: &EnvRegistry) -> Result<PoolRun, String> {
        let worker = WorkerCommand::current_exe(&["worker"]).map_err(|e| e.to_string())?;
        let mut cfg = PoolConfig::new(spec.clone(), a.envs, a.workers, worker);
        cfg.seeds.base = a.seed;
        cfg.wait = WaitPolicy {
            poll_budget: Duration::from_micros(a.poll_us),
            yield_cpu: !a.spin,
            ..cfg.wait
        };
        cfg.worker_wait = WaitPolicy {
            poll_budget: Duration::from_micros(a.worker_poll_us),
            yield_cpu: !a.worker_spin,
            ..cfg.worker_wait
        };
        let epw = a.envs / a.workers.max(1);
        if a.mode == Mode::Async {
            let b = a.batch_size.unwrap_or(if a.workers >= 2 {
                (a.workers / 2) * epw
            } else {
                a.envs
            });
            cfg.batch_size = Some(b);
        }
        let mut pool = Pool::new(cfg, reg).map_err(|e| e.to_string())?;
        let n = a.envs;
        let mut obs = vec![0u8; n * pool.obs_bytes()];
        let mut out = BatchOutput::default();
        match a.mode {
            Mode::Sync => pool
                .reset(None)
                .and_then(|r| pool.read_rows(&r, Some(&mut obs), &mut out)),
            Mode::Shared => pool.reset(None).map(drop),
            Mode::Async => pool.async_reset(),
        }
        .map_err(|e| e.to_string())?;
        let na = pool.spec().num_actions as u64;
        Ok(PoolRun {
            pool,
            mode: a.mode,
            obs,
            out,
            actions: vec![0; n],
            rng: Rng(0x2545_F491_4F6C_DD1D ^ a.seed),
            lat: Vec::new(),
            na,
        })
    }

    /// Run `batches` batches; returns (time, env steps).
    fn run(&mut self, batches: u64) -> Result<(Duration, u64), String> {
        let mut env_steps = 0u64;
        let t0 = Instant::now();
        for _ in 0..batches {
            let t = Instant::now();
            match self.mode {
                Mode::Sync | Mode::Shared => {
                    for x in self.actions.iter_mut() {
                        *x = (self.rng.next() % self.na) as i64;
                    }
                    // Shared: the rows stay in the slot, where a binding reads them; sync
                    // copies them out.
                    let copy = self.mode == Mode::Sync;
                    self.pool
                        .step(&self.actions)
                        .and_then(|r| match copy {
                            true => self.pool.read_rows(&r, Some(&mut self.obs), &mut self.out),
                            false => Ok(()),
                        })
                        .map_err(|e| e.to_string())?;
                    env_steps += self.actions.len() as u64;
                    self.lat.push(t.elapsed());
                }
                Mode::Async => {
                    let got = self.pool.recv().map_err(|e| e.to_string())?;
                    self.lat.push(t.elapsed());
                    let ids = got.env_ids;
                    env_steps += ids.len() as u64;
                    self.actions.clear();
                    for _ in &ids {
                        self.actions.push((self.rng.next() % self.na) as i64);
                    }
                    self.pool
                        .send(&self.actions, &ids)
                        .map_err(|e| e.to_string())?;
                }
            }
        }
        Ok((t0.elapsed(), env_steps))
    }
}

/// Run the benchmark; returns the exit code.
pub fn run(a: Args) -> i32 {
    match bench(&a) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("pool-bench: {e}");
            1
        }
    }
}

fn bench(a: &Args) -> Result<(), String> {
    if a.envs == 0 || a.workers == 0 || !a.envs.is_multiple_of(a.workers) {
        return Err(format!(
            "--envs ({}) must be a positive multiple of --workers ({})",
            a.envs, a.workers
        ));
    }
    let reg = EnvRegistry::with_defaults();
    let spec = env_spec(a)?;
    let s = reg.make(&spec, 0).map_err(|e| e.to_string())?.spec();
    let rounds = a.rounds.max(1);
    println!(
        "pool-bench: env={} envs={} workers={} mode={:?} steps={} (in {rounds} interleaved rounds) obs={:?} {} ({} B)",
        a.env,
        a.envs,
        a.workers,
        a.mode,
        a.steps,
        s.obs_shape,
        s.dtype.numpy_name(),
        s.obs_bytes()
    );
    let mut raw = Raw::new(&spec, a, &reg)?;
    let mut pool = PoolRun::new(&spec, a, &reg)?;
    // Warm up both, then alternate raw and pool chunks so that both see the same machine load.
    let warm = (a.steps / 10).max(1);
    raw.run(warm)?;
    pool.run(warm)?;
    pool.lat.clear();
    let chunk = (a.steps / rounds).max(1);
    let (mut raw_t, mut pool_t, mut pool_steps) = (Duration::ZERO, Duration::ZERO, 0u64);
    for _ in 0..rounds {
        raw_t += raw.run(chunk)?;
        let (t, n) = pool.run(chunk)?;
        pool_t += t;
        pool_steps += n;
    }
    let raw_rate = (a.envs as u64 * chunk * rounds) as f64 / raw_t.as_secs_f64();
    let pool_rate = pool_steps as f64 / pool_t.as_secs_f64();
    let bs = if a.mode == Mode::Async {
        pool.pool.batch_size()
    } else {
        a.envs
    };
    let (p50, p99) = (pct(&mut pool.lat, 0.5), pct(&mut pool.lat, 0.99));
    pool.pool.close().map_err(|e| e.to_string())?;
    println!("raw single-process loop: {raw_rate:>12.0} env-steps/s");
    println!(
        "pool ({:<6})           : {pool_rate:>12.0} env-steps/s   batch of {bs}: p50 {p50:.1} us, p99 {p99:.1} us",
        format!("{:?}", a.mode).to_lowercase()
    );
    println!(
        "pool / raw             : {:>11.1} %",
        100.0 * pool_rate / raw_rate
    );
    Ok(())
}
