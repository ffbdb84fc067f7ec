//! Shared helpers for the end-to-end tests in this folder.

#![deny(missing_docs)]

use std::path::PathBuf;
use std::process::Child;
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;

use rogue_gym_pool::{
    Actions, AutoresetMode, BatchOutput, EnvRegistry, Pool, PoolConfig, PoolError, WorkerCommand,
    seeds::splitmix,
};

/// The pool's whole-batch calls with their rows copied out ([`Pool::read_rows`]): into
/// `obs` and `out` (`*_into`), or into `out` alone, returning the slot (`*_read`).
pub trait Copying {
    /// [`Pool::reset`], copied out.
    fn reset_into(&mut self, obs: &mut [u8], out: &mut BatchOutput) -> Result<(), PoolError>;
    /// [`Pool::step`], copied out.
    fn step_into<'a>(
        &mut self,
        actions: impl Into<Actions<'a>>,
        obs: &mut [u8],
        out: &mut BatchOutput,
    ) -> Result<(), PoolError>;
    /// [`Pool::reset`] with a mask, copied out.
    fn partial_reset_into(
        &mut self,
        mask: &[bool],
        obs: &mut [u8],
        out: &mut BatchOutput,
    ) -> Result<(), PoolError>;
    /// [`Pool::reset`], records read into `out`; the slot.
    fn reset_read(&mut self, out: &mut BatchOutput) -> Result<usize, PoolError>;
    /// [`Pool::step`], records read into `out`; the slot.
    fn step_read<'a>(
        &mut self,
        actions: impl Into<Actions<'a>>,
        out: &mut BatchOutput,
    ) -> Result<usize, PoolError>;
    /// [`Pool::reset`] with a mask, records read into `out`; the slot.
    fn partial_reset_read(
        &mut self,
        mask: &[bool],
        out: &mut BatchOutput,
    ) -> Result<usize, PoolError>;
}

impl Copying for Pool {
    fn reset_into(&mut self, obs: &mut [u8], out: &mut BatchOutput) -> Result<(), PoolError> {
        let a = self.reset(None)?;
        self.read_rows(&a, Some(obs), out)
    }
    fn step_into<'a>(
        &mut self,
        actions: impl Into<Actions<'a>>,
        obs: &mut [u8],
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        let a = self.step(actions)?;
        self.read_rows(&a, Some(obs), out)
    }
    fn partial_reset_into(
        &mut self,
        mask: &[bool],
        obs: &mut [u8],
        out: &mut BatchOutput,
    ) -> Result<(), PoolError> {
        let a = self.reset(Some(mask))?;
        self.read_rows(&a, Some(obs), out)
    }
    fn reset_read(&mut self, out: &mut BatchOutput) -> Result<usize, PoolError> {
        let a = self.reset(None)?;
        self.read_rows(&a, None, out)?;
        Ok(a.slot()
            .expect("a whole-batch call's result is a view of its slot"))
    }
    fn step_read<'a>(
        &mut self,
        actions: impl Into<Actions<'a>>,
        out: &mut BatchOutput,
    ) -> Result<usize, PoolError> {
        let a = self.step(actions)?;
        self.read_rows(&a, None, out)?;
        Ok(a.slot()
            .expect("a whole-batch call's result is a view of its slot"))
    }
    fn partial_reset_read(
        &mut self,
        mask: &[bool],
        out: &mut BatchOutput,
    ) -> Result<usize, PoolError> {
        let a = self.reset(Some(mask))?;
        self.read_rows(&a, None, out)?;
        Ok(a.slot()
            .expect("a whole-batch call's result is a view of its slot"))
    }
}

/// Runtime directory of the pools created by the tests (short: unix socket paths < 108
/// bytes), created private (0700) if missing.
pub fn test_base() -> PathBuf {
    let dir = PathBuf::from("/tmp/rge2e");
    rogue_gym_ipc::private::ensure_private_dir(&dir).expect("a private test runtime directory");
    dir
}

/// The worker command of the e2e binary (`<exe> worker ...`).
pub fn worker_cmd(exe: &str) -> WorkerCommand {
    WorkerCommand {
        program: PathBuf::from(exe),
        args: vec!["worker".into()],
    }
}

/// A pool config for the e2e tests.
pub fn config(exe: &str, env: serde_json::Value, num_envs: usize, workers: usize) -> PoolConfig {
    let mut c = PoolConfig::new(env, num_envs, workers, worker_cmd(exe));
    c.runtime_dir = Some(test_base());
    c.seeds.base = 1234;
    c
}

/// Deterministic action of env `env` at its `t`-th step.
pub fn action(env: usize, t: u64, num_actions: usize) -> i64 {
    (splitmix((env as u64) << 32 ^ t) % num_actions as u64) as i64
}

/// Per-env running digest of a trajectory (obs bytes, reward, flags, episode, seed).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Digests(pub Vec<u64>);

impl Digests {
    /// Empty digests for `n` envs.
    pub fn new(n: usize) -> Self {
        Digests(vec![0xcbf2_9ce4_8422_2325; n])
    }
    /// Fold one row in.
    pub fn add(&mut self, env: usize, obs: &[u8], out: &BatchOutput, row: usize) {
        let mut h = self.0[env];
        let mut eat = |x: u64| h = splitmix(h ^ x);
        for c in obs.chunks(8) {
            let mut b = [0u8; 8];
            b[..c.len()].copy_from_slice(c);
            eat(u64::from_le_bytes(b));
        }
        eat(out.reward[row].to_bits());
        eat(u64::from(out.terminated[row]) | u64::from(out.truncated[row]) << 1);
        eat(out.episode[row]);
        eat(out.seed[row]);
        eat(out.episode_return[row].to_bits());
        self.0[env] = h;
    }
    /// Fold a whole sync batch in.
    pub fn add_batch(&mut self, obs: &[u8], obs_bytes: usize, out: &BatchOutput) {
        for (row, &env) in out.env_ids.iter().enumerate() {
            self.add(env, &obs[row * obs_bytes..(row + 1) * obs_bytes], out, row);
        }
    }
}

/// Run `steps` sync steps after a reset with the deterministic actions; per-env digests.
pub fn run_sync(pool: &mut Pool, steps: u64) -> Result<Digests, PoolError> {
    let n = pool.num_envs();
    let ob = pool.obs_bytes();
    let na = pool.spec().num_actions;
    let mut obs = vec![0u8; n * ob];
    let mut out = BatchOutput::default();
    let mut d = Digests::new(n);
    pool.reset_into(&mut obs, &mut out)?;
    d.add_batch(&obs, ob, &out);
    for t in 0..steps {
        let actions: Vec<i64> = (0..n).map(|i| action(i, t, na)).collect();
        pool.step_into(&actions, &mut obs, &mut out)?;
        d.add_batch(&obs, ob, &out);
    }
    Ok(d)
}

/// [`run_sync`] reading the shared batch slots in place (`reset_read`/`step_read`, no copy);
/// also checks the double buffering (a step leaves the previous step's slot unchanged).
pub fn run_sync_shared(pool: &mut Pool, steps: u64) -> Result<Digests, PoolError> {
    let n = pool.num_envs();
    let ob = pool.obs_bytes();
    let na = pool.spec().num_actions;
    let mut out = BatchOutput::default();
    let mut d = Digests::new(n);
    let mut slot = pool.reset_read(&mut out)?;
    d.add_batch(pool.shared_obs(slot), ob, &out);
    for t in 0..steps {
        let actions: Vec<i64> = (0..n).map(|i| action(i, t, na)).collect();
        let (prev, snapshot) = (slot, pool.shared_obs(slot).to_vec());
        slot = pool.step_read(&actions, &mut out)?;
        assert_ne!(slot, prev, "slots alternate");
        assert!(
            pool.shared_obs(prev) == &snapshot[..],
            "previous slot unchanged"
        );
        d.add_batch(pool.shared_obs(slot), ob, &out);
    }
    Ok(d)
}

/// The same trajectories through the async API (`async_reset`, then `recv`/`send` until every
/// env did `steps` steps; blocks that finish early keep stepping, unrecorded, so that every
/// `recv` finds a full batch).
pub fn run_async(pool: &mut Pool, steps: u64) -> Result<Digests, PoolError> {
    let n = pool.num_envs();
    let ob = pool.obs_bytes();
    let na = pool.spec().num_actions;
    let mut d = Digests::new(n);
    // Results received per env (the reset counts as the first).
    let mut got = vec![0u64; n];
    pool.async_reset()?;
    while got.iter().any(|&g| g < steps + 1) {
        let got_now = pool.recv()?;
        // A view (`set_async_views`) or gathered rows, copied out alike.
        let (mut out, mut obs) = (BatchOutput::default(), vec![0; got_now.env_ids.len() * ob]);
        pool.read_rows(&got_now, Some(&mut obs), &mut out)?;
        for (row, &e) in out.env_ids.iter().enumerate() {
            if got[e] < steps + 1 {
                d.add(e, &obs[row * ob..(row + 1) * ob], &out, row);
            }
            got[e] += 1;
        }
        let ids = out.env_ids.clone();
        let actions: Vec<i64> = ids.iter().map(|&e| action(e, got[e] - 1, na)).collect();
        pool.send(&actions, &ids)?;
    }
    Ok(d)
}

/// Whether process `pid` is alive (exists and is not a zombie).
pub fn alive(pid: u32) -> bool {
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        Ok(s) => s
            .rsplit_once(')')
            .and_then(|(_, r)| r.split_whitespace().next())
            .is_some_and(|state| state != "Z" && state != "X"),
        Err(_) => false,
    }
}

/// Kills a child process (and reaps it) when dropped, even if the test fails.
pub struct ChildGuard(pub Option<Child>);

impl Drop for ChildGuard {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Sends SIGKILL to the given pids when dropped (workers a test may leave behind on failure).
pub struct PidGuard(pub Vec<u32>);

impl Drop for PidGuard {
    fn drop(&mut self) {
        for &p in &self.0 {
            if alive(p) {
                let _ = nix::sys::signal::kill(
                    nix::unistd::Pid::from_raw(p as i32),
                    nix::sys::signal::Signal::SIGKILL,
                );
            }
        }
    }
}

/// Sweeps the pools of dead owners under a base directory when dropped (files of a killed
/// supervisor, even if the test fails before its own sweep).
pub struct SweepGuard(pub PathBuf);

impl Drop for SweepGuard {
    fn drop(&mut self) {
        rogue_gym_ipc::sweep_stale_pools(&self.0);
        let _ = std::fs::remove_dir(&self.0);
    }
}

/// Whether the pool's files are all gone.
pub fn pool_files_gone(id: &rogue_gym_ipc::PoolId) -> bool {
    rogue_gym_ipc::pool_shm_files(id).is_empty() && !id.root().exists() && !id.aux_dir().exists()
}

/// The SAME_STEP variant of a config.
pub fn same_step(mut c: PoolConfig) -> PoolConfig {
    c.autoreset = AutoresetMode::SameStep;
    c
}

/// The deterministic test env of these tests: 3x5x7 observations, 12-step episodes, 5 actions.
pub fn test_env() -> serde_json::Value {
    serde_json::json!({"kind": "test", "obs_shape": [3, 5, 7], "max_steps": 12, "num_actions": 5})
}

/// A started pool with the default env registry.
pub fn pool(c: PoolConfig) -> Pool {
    Pool::new(c, &EnvRegistry::with_defaults()).expect("pool starts")
}

/// Send a signal and wait until it took effect (killed: dead or zombie; stopped: state T), so
/// the worker cannot answer one more command in between.
pub fn signal(pid: u32, s: Signal) {
    kill(Pid::from_raw(pid as i32), s).expect("signal worker");
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(5) {
        let state = std::fs::read_to_string(format!("/proc/{pid}/stat"))
            .ok()
            .and_then(|st| {
                st.rsplit_once(')')
                    .and_then(|(_, r)| r.split_whitespace().next().map(str::to_string))
            });
        let done = match (s, state.as_deref()) {
            (_, None) => true,
            (Signal::SIGSTOP, Some(st)) => st == "T" || st == "t",
            (_, Some(st)) => st == "Z" || st == "X",
        };
        if done {
            return;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    panic!("signal {s} to {pid} did not take effect");
}
