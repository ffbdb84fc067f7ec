//! End-to-end tests of the pool with real worker processes (the `e2e_worker` binary) hosting
//! the deterministic test env: determinism, crash and hang handling, cleanup, errors.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use rogue_gym_e2e::*;
use rogue_gym_pool::{
    BatchOutput, EnvRegistry, FailurePolicy, Pool, PoolConfig, PoolError, SeedPolicy, SeedSet,
};
use serde_json::json;

const EXE: &str = env!("CARGO_BIN_EXE_e2e_worker");

fn test_env() -> serde_json::Value {
    json!({"kind": "test", "obs_shape": [3, 5, 7], "max_steps": 12, "num_actions": 5})
}

fn pool(c: PoolConfig) -> Pool {
    Pool::new(c, &EnvRegistry::with_defaults()).expect("pool starts")
}

/// Send a signal and wait until it took effect (killed: dead or zombie; stopped: state T), so
/// the worker cannot answer one more command in between.
fn signal(pid: u32, s: Signal) {
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

#[test]
fn trajectories_identical_for_1_2_4_workers_and_sync_async() {
    let steps = 40;
    let mut reference = None;
    for workers in [1, 2, 4] {
        let mut p = pool(config(EXE, test_env(), 8, workers));
        let d = run_sync(&mut p, steps).unwrap();
        let id = p.id().clone();
        p.close().unwrap();
        assert!(pool_files_gone(&id));
        match &reference {
            None => reference = Some(d),
            Some(r) => assert_eq!(&d, r, "sync with {workers} workers differs"),
        }
    }
    let reference = reference.unwrap();
    for workers in [1, 2, 4] {
        let mut p = pool(config(EXE, test_env(), 8, workers));
        let d = run_sync_shared(&mut p, steps).unwrap();
        assert_eq!(
            d, reference,
            "shared-slot sync with {workers} workers differs"
        );
    }
    for (workers, batch) in [(4, 4), (2, 4), (4, 8)] {
        let mut c = config(EXE, test_env(), 8, workers);
        c.batch_size = Some(batch);
        let mut p = pool(c);
        let d = run_async(&mut p, steps).unwrap();
        assert_eq!(
            d, reference,
            "async with {workers} workers, batch {batch} differs"
        );
    }
}

#[test]
fn same_step_mode_is_deterministic_and_returns_final_obs() {
    let mut a = pool(same_step(config(EXE, test_env(), 4, 1)));
    let mut b = pool(same_step(config(EXE, test_env(), 4, 2)));
    assert_eq!(run_sync(&mut a, 30).unwrap(), run_sync(&mut b, 30).unwrap());
    // Episodes end within max_steps = 12: final observations are reported.
    let ob = a.obs_bytes();
    let mut obs = vec![0u8; 4 * ob];
    let mut out = BatchOutput::default();
    a.reset(&mut obs, &mut out).unwrap();
    let mut seen_final = false;
    for _ in 0..13 {
        a.step(&[1, 1, 1, 1], &mut obs, &mut out).unwrap();
        for r in 0..4 {
            let done = out.terminated[r] || out.truncated[r];
            assert_eq!(out.has_final_obs[r], done);
            if done {
                seen_final = true;
                assert_eq!(out.final_obs.len(), 4 * ob);
                assert!(out.episode_length[r] <= 12);
            }
        }
    }
    assert!(seen_final);
}

#[test]
fn seed_sets_sequential_policy_through_the_pool() {
    let mut c = config(EXE, test_env(), 4, 2);
    c.seeds.set = Some(SeedSet::Range {
        start: 1000,
        end: 1008,
    });
    c.seeds.policy = SeedPolicy::Sequential;
    let mut p = pool(c);
    let mut obs = vec![0u8; 4 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset(&mut obs, &mut out).unwrap();
    assert_eq!(out.seed, vec![1000, 1001, 1002, 1003]);
    p.reset(&mut obs, &mut out).unwrap();
    assert_eq!(out.seed, vec![1004, 1005, 1006, 1007]);
    assert_eq!(out.episode, vec![1, 1, 1, 1]);
}

#[test]
fn killed_worker_is_restarted_and_other_envs_are_untouched() {
    killed_worker_case(false);
}

#[test]
fn killed_worker_is_restarted_in_shared_slot_mode() {
    killed_worker_case(true);
}

fn killed_worker_case(shared: bool) {
    let steps = 30u64;
    let mut clean = pool(config(EXE, test_env(), 8, 2));
    let reference = run_sync(&mut clean, steps).unwrap();
    drop(clean);

    let mut p = pool(config(EXE, test_env(), 8, 2));
    let _guard = PidGuard(p.worker_pids());
    let n = 8;
    let ob = p.obs_bytes();
    let mut obs = vec![0u8; n * ob];
    let mut out = BatchOutput::default();
    let mut d = Digests::new(n);
    if shared {
        let slot = p.reset_shared(&mut out).unwrap();
        obs.copy_from_slice(p.shared_obs(slot));
    } else {
        p.reset(&mut obs, &mut out).unwrap();
    }
    d.add_batch(&obs, ob, &out);
    let victim = p.worker_pids()[0];
    let mut restarted_rows = 0;
    let mut episodes_before = vec![0u64; n];
    for t in 0..steps {
        if t == 10 {
            episodes_before = out.episode.clone();
            signal(victim, Signal::SIGKILL);
        }
        let actions: Vec<i64> = (0..n).map(|i| action(i, t, 5)).collect();
        if shared {
            let slot = p.step_shared(&actions, &mut out).unwrap();
            obs.copy_from_slice(p.shared_obs(slot));
        } else {
            p.step(&actions, &mut obs, &mut out).unwrap();
        }
        d.add_batch(&obs, ob, &out);
        #[allow(clippy::needless_range_loop)]
        for r in 0..n {
            if out.restarted[r] {
                restarted_rows += 1;
                assert!(r < 4, "only worker 0's envs restart");
                assert_eq!(t, 10, "the restart is reported on the step after the kill");
                assert!(out.truncated[r] && !out.terminated[r]);
                assert_eq!(out.reward[r], 0.0);
                assert_eq!(out.episode_length[r], 0);
                assert!(
                    out.episode[r] > episodes_before[r],
                    "a restarted env starts its next scheduled episode"
                );
            }
        }
    }
    assert_eq!(restarted_rows, 4);
    assert_eq!(p.restarts(), 1);
    assert_ne!(p.worker_pids()[0], victim);
    assert!(!alive(victim));
    assert_eq!(
        &d.0[4..],
        &reference.0[4..],
        "worker 1's envs match the uncrashed run"
    );
    assert_ne!(&d.0[..4], &reference.0[..4]);
    let id = p.id().clone();
    p.close().unwrap();
    assert!(pool_files_gone(&id), "no file left after a crash and close");
}

#[test]
fn hung_worker_is_restarted_after_step_timeout() {
    let mut c = config(EXE, test_env(), 4, 2);
    c.step_timeout = Some(Duration::from_millis(300));
    let mut p = pool(c);
    let _guard = PidGuard(p.worker_pids());
    let mut obs = vec![0u8; 4 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset(&mut obs, &mut out).unwrap();
    let victim = p.worker_pids()[1];
    signal(victim, Signal::SIGSTOP);
    let t0 = Instant::now();
    p.step(&[0, 1, 2, 3], &mut obs, &mut out).unwrap();
    assert!(t0.elapsed() >= Duration::from_millis(300));
    assert_eq!(out.restarted, vec![false, false, true, true]);
    assert_eq!(out.truncated[2..], [true, true]);
    assert!(!alive(victim), "the hung worker was killed");
    p.step(&[0, 1, 2, 3], &mut obs, &mut out).unwrap();
    assert_eq!(out.restarted, vec![false; 4]);
}

#[test]
fn raise_policy_reports_hangs_and_kills_then_recovers_after_reset() {
    let mut c = config(EXE, test_env(), 4, 2);
    c.step_timeout = Some(Duration::from_millis(300));
    c.on_worker_failure = FailurePolicy::Raise;
    let mut p = pool(c);
    let _guard = PidGuard(p.worker_pids());
    let mut obs = vec![0u8; 4 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset(&mut obs, &mut out).unwrap();

    let victim = p.worker_pids()[0];
    signal(victim, Signal::SIGSTOP);
    let e = p.step(&[0, 1, 2, 3], &mut obs, &mut out).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, PoolError::WorkerFailed(_)), "{msg}");
    assert!(msg.contains(&format!("pid {victim}")), "{msg}");
    assert!(msg.contains("envs 0..2") && msg.contains("hung"), "{msg}");
    // The pool respawned the worker; it needs a reset.
    assert!(matches!(
        p.step(&[0, 1, 2, 3], &mut obs, &mut out),
        Err(PoolError::State(_))
    ));
    p.reset(&mut obs, &mut out).unwrap();
    p.step(&[0, 1, 2, 3], &mut obs, &mut out).unwrap();

    let victim = p.worker_pids()[1];
    signal(victim, Signal::SIGKILL);
    let e = p.step(&[0, 1, 2, 3], &mut obs, &mut out).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("signal 9 (SIGKILL)") && msg.contains("envs 2..4"),
        "{msg}"
    );
    p.reset(&mut obs, &mut out).unwrap();
    p.step(&[0, 1, 2, 3], &mut obs, &mut out).unwrap();
}

#[test]
fn env_failure_in_worker_reports_its_stderr() {
    let mut c = config(
        EXE,
        json!({"kind": "test", "obs_shape": [4], "fail_on_action": 3}),
        2,
        1,
    );
    c.on_worker_failure = FailurePolicy::Raise;
    let mut p = pool(c);
    let mut obs = vec![0u8; 2 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset(&mut obs, &mut out).unwrap();
    let e = p.step(&[0, 3], &mut obs, &mut out).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("exited with code 3"), "{msg}");
    assert!(msg.contains("injected failure on action 3"), "{msg}");
}

#[test]
fn restart_budget_is_enforced() {
    let mut c = config(EXE, test_env(), 2, 1);
    c.max_restarts = 0;
    let mut p = pool(c);
    let _guard = PidGuard(p.worker_pids());
    let mut obs = vec![0u8; 2 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset(&mut obs, &mut out).unwrap();
    signal(p.worker_pids()[0], Signal::SIGKILL);
    let e = p.step(&[0, 0], &mut obs, &mut out).unwrap_err();
    assert!(matches!(e, PoolError::RestartBudgetExceeded { .. }), "{e}");
    assert!(e.to_string().contains("restart budget exhausted"));
}

#[test]
fn bad_input_is_an_error_value() {
    let mut p = pool(config(EXE, test_env(), 4, 2));
    let mut obs = vec![0u8; 4 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    let e = p.step(&[0, 0, 0, 0], &mut obs, &mut out).unwrap_err();
    assert!(e.to_string().contains("reset()"), "{e}");
    p.reset(&mut obs, &mut out).unwrap();
    let e = p.step(&[0, 0, 0], &mut obs, &mut out).unwrap_err();
    assert_eq!(
        e.to_string(),
        "got 3 actions for 4 envs: pass exactly one action per env"
    );
    let e = p.step(&[0, 0, 7, 0], &mut obs, &mut out).unwrap_err();
    assert_eq!(
        e.to_string(),
        "env 2: action 7 is out of range; valid actions are 0..5"
    );
    let e = p.step(&[0; 4], &mut obs[1..], &mut out).unwrap_err();
    assert!(matches!(e, PoolError::BadBuffer { .. }));
    // Async misuse.
    let e = p.send(&[0, 0], &[1, 2]).unwrap_err();
    assert!(e.to_string().contains("worker block"), "{e}");
    let e = p.recv().unwrap_err();
    assert!(e.to_string().contains("send()"), "{e}");
    // The pool still works.
    p.step(&[0, 1, 2, 3], &mut obs, &mut out).unwrap();

    // Config errors.
    let reg = EnvRegistry::with_defaults();
    let e = Pool::new(config(EXE, test_env(), 5, 2), &reg).unwrap_err();
    assert!(e.to_string().contains("multiple of num_workers"), "{e}");
    let e = Pool::new(config(EXE, json!({"kind": "nope"}), 2, 1), &reg).unwrap_err();
    assert!(e.to_string().contains("unknown env kind"), "{e}");
    // A worker that cannot start: its stderr is in the error.
    let mut c = config(EXE, test_env(), 2, 1);
    c.worker.args = vec!["bogus".into()];
    let e = Pool::new(c, &reg).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("failed to start") && msg.contains("usage"),
        "{msg}"
    );
    let mut c = config(EXE, test_env(), 2, 1);
    c.worker.program = "/nonexistent/worker".into();
    let e = Pool::new(c, &reg).unwrap_err();
    assert!(e.to_string().contains("cannot execute"), "{e}");
}

#[test]
fn async_blocks_are_zero_copy_and_outlive_the_pool() {
    let mut c = config(EXE, test_env(), 4, 2);
    c.batch_size = Some(2);
    let mut p = pool(c);
    p.async_reset().unwrap();
    let b1 = p.recv().unwrap();
    let b2 = p.recv().unwrap();
    let mut ids = [b1.env_ids(), b2.env_ids()].concat();
    ids.sort();
    assert_eq!(ids, vec![0, 1, 2, 3]);
    let snapshot: Vec<u8> = b1.blocks[0].obs().to_vec();
    assert_eq!(snapshot.len(), 2 * p.obs_bytes());
    // Step the other block while holding b1.
    let other = b2.env_ids();
    p.send(&[1, 1], &other).unwrap();
    let b3 = p.recv().unwrap();
    assert_eq!(b3.env_ids(), other);
    let id = p.id().clone();
    p.close().unwrap();
    assert!(pool_files_gone(&id));
    // Held samples stay mapped and unchanged after close.
    assert_eq!(b1.blocks[0].obs(), &snapshot[..]);
    drop((b1, b2, b3));
}

#[test]
fn two_pools_at_once_do_not_interfere() {
    let mut a = pool(config(EXE, test_env(), 4, 2));
    let mut b = pool(config(EXE, test_env(), 4, 2));
    assert_ne!(a.id().name(), b.id().name());
    let (da, db) = std::thread::scope(|s| {
        let ha = s.spawn(|| run_sync(&mut a, 20).unwrap());
        let hb = s.spawn(|| run_sync(&mut b, 20).unwrap());
        (ha.join().unwrap(), hb.join().unwrap())
    });
    assert_eq!(da, db, "same config, same trajectories");
    let (ia, ib) = (a.id().clone(), b.id().clone());
    drop(a);
    assert!(pool_files_gone(&ia));
    assert!(
        !pool_files_gone(&ib),
        "closing one pool leaves the other alone"
    );
    drop(b);
    assert!(pool_files_gone(&ib));
}

#[test]
fn killed_supervisor_leaves_no_worker_and_its_files_are_swept() {
    let base = test_base().join("sk");
    let _sweep = SweepGuard(base.clone());
    let child = Command::new(EXE)
        .args(["hold-pool", "2"])
        .arg(&base)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut guard = ChildGuard(Some(child));
    let stdout = guard.0.as_mut().unwrap().stdout.take().unwrap();
    let mut lines = BufReader::new(stdout).lines();
    let name = lines.next().unwrap().unwrap();
    let name = name.strip_prefix("pool ").unwrap().to_string();
    let pids_line = lines.next().unwrap().unwrap();
    let pids: Vec<u32> = pids_line
        .strip_prefix("pids ")
        .unwrap()
        .split_whitespace()
        .map(|p| p.parse().unwrap())
        .collect();
    let _pg = PidGuard(pids.clone());
    assert_eq!(pids.len(), 2);
    assert!(pids.iter().all(|&p| alive(p)));
    // kill -9 the supervisor.
    guard.0.as_mut().unwrap().kill().unwrap();
    guard.0.take().unwrap().wait().unwrap();
    let t0 = Instant::now();
    while pids.iter().any(|&p| alive(p)) && t0.elapsed() < Duration::from_secs(5) {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(
        pids.iter().all(|&p| !alive(p)),
        "workers survived their supervisor"
    );
    // Its files stay until a sweep (here: the next pool start in the same base).
    let id = rogue_gym_ipc::PoolId::from_parts(&name, &base).unwrap();
    assert!(!pool_files_gone(&id));
    let swept = rogue_gym_ipc::sweep_stale_pools(&base);
    assert!(swept.contains(&name), "{swept:?}");
    assert!(pool_files_gone(&id));
    let _ = std::fs::remove_dir(&base);
}

#[test]
fn shared_slots_stay_mapped_through_their_arc_after_close() {
    let mut p = pool(config(EXE, test_env(), 4, 2));
    let mut out = BatchOutput::default();
    let slot = p.reset_shared(&mut out).unwrap();
    let snapshot = p.shared_obs(slot).to_vec();
    let buf = p.shared_buffer().unwrap();
    let offset = slot * p.shared_slot_bytes();
    let id = p.id().clone();
    p.close().unwrap();
    assert!(pool_files_gone(&id));
    assert!(p.shared_obs_ptr(slot).is_null());
    // SAFETY: the Arc keeps the mapping alive; the range lies inside it.
    let view = unsafe { std::slice::from_raw_parts(buf.as_ptr().add(offset), snapshot.len()) };
    assert_eq!(view, &snapshot[..]);
}

#[test]
fn async_mode_reports_a_restarted_block() {
    let mut c = config(EXE, test_env(), 4, 2);
    c.batch_size = Some(2);
    let mut p = pool(c);
    let _guard = PidGuard(p.worker_pids());
    p.async_reset().unwrap();
    let b0 = p.recv().unwrap();
    let b1 = p.recv().unwrap();
    let ids0 = b0.env_ids();
    let ids1 = b1.env_ids();
    drop((b0, b1));
    let victim_worker = ids0[0] / 2;
    signal(p.worker_pids()[victim_worker], Signal::SIGKILL);
    p.send(&[1, 1], &ids0).unwrap();
    p.send(&[1, 1], &ids1).unwrap();
    let mut restarted = Vec::new();
    for _ in 0..2 {
        let b = p.recv().unwrap();
        let blk = &b.blocks[0];
        for j in 0..2 {
            let r = blk.record(j);
            if r.restarted() {
                assert!(r.truncated() && !r.terminated());
                restarted.push(blk.env_ids().start + j);
            }
        }
    }
    assert_eq!(restarted, ids0);
    assert_eq!(p.restarts(), 1);
}

#[test]
fn set_seeds_then_reset_replays_a_fresh_pool() {
    let mut fresh = pool(config(EXE, test_env(), 4, 2));
    let reference = run_sync(&mut fresh, 20).unwrap();
    let mut c = config(EXE, test_env(), 4, 2);
    c.seeds.base = 7;
    let mut p = pool(c);
    let other = run_sync(&mut p, 20).unwrap();
    assert_ne!(other, reference);
    p.set_seeds(rogue_gym_pool::SeedSchedule::from_base(1234))
        .unwrap();
    let mut obs = vec![0u8; 4 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    assert!(
        p.step(&[0; 4], &mut obs, &mut out).is_err(),
        "reset required"
    );
    assert_eq!(run_sync(&mut p, 20).unwrap(), reference);
}

/// One sync batch as seen by the caller: observations and the per-env arrays.
type Frame = (Vec<u8>, BatchOutput);

/// Reset, `steps` steps with the deterministic actions, then (if `mask`) a partial reset after
/// step `at`; shared-slot sync API (`copy`: the copying API instead). All frames returned.
fn masked_run(workers: usize, steps: u64, mask: Option<(u64, &[bool])>, copy: bool) -> Vec<Frame> {
    let mut p = pool(config(EXE, test_env(), 8, workers));
    let n = p.num_envs();
    let ob = p.obs_bytes();
    let mut obs = vec![0u8; n * ob];
    let mut out = BatchOutput::default();
    let mut frames = Vec::new();
    let mut grab = |p: &Pool, slot: Option<usize>, obs: &[u8], out: &BatchOutput| {
        let o = slot.map_or_else(|| obs.to_vec(), |s| p.shared_obs(s).to_vec());
        frames.push((o, out.clone()));
    };
    if copy {
        p.reset(&mut obs, &mut out).unwrap();
        grab(&p, None, &obs, &out);
    } else {
        let s = p.reset_shared(&mut out).unwrap();
        grab(&p, Some(s), &obs, &out);
    }
    for t in 0..steps {
        let actions: Vec<i64> = (0..n).map(|i| action(i, t, 5)).collect();
        if copy {
            p.step(&actions, &mut obs, &mut out).unwrap();
            grab(&p, None, &obs, &out);
        } else {
            let s = p.step_shared(&actions, &mut out).unwrap();
            grab(&p, Some(s), &obs, &out);
        }
        if let Some((at, m)) = mask
            && at == t
        {
            if copy {
                p.reset_envs_into(m, &mut obs, &mut out).unwrap();
                grab(&p, None, &obs, &out);
            } else {
                let s = p.reset_envs(m, &mut out).unwrap();
                grab(&p, Some(s), &obs, &out);
            }
        }
    }
    frames
}

#[test]
fn partial_reset_resets_exactly_the_masked_envs() {
    let (steps, at) = (30, 14);
    let mask = [false, true, true, false, false, false, true, false];
    let reference = masked_run(2, steps, None, false);
    let run = masked_run(2, steps, Some((at, &mask)), false);
    assert_eq!(run.len(), reference.len() + 1);
    let ob = {
        let p = pool(config(EXE, test_env(), 1, 1));
        p.obs_bytes()
    };
    let seeds = rogue_gym_pool::SeedSchedule::from_base(1234);
    // Frame `at + 1` is the last step before the partial reset, `at + 2` the reset itself.
    let (before_obs, before) = &run[at as usize + 1];
    let (obs, out) = &run[at as usize + 2];
    assert_eq!(out.env_ids, (0..8).collect::<Vec<_>>());
    for i in 0..8 {
        let o = &obs[i * ob..(i + 1) * ob];
        assert_eq!(out.reward[i], 0.0);
        assert!(!out.terminated[i] && !out.truncated[i] && !out.restarted[i]);
        if mask[i] {
            assert_eq!(
                out.episode[i],
                before.episode[i] + 1,
                "env {i}: next episode"
            );
            assert_eq!(out.seed[i], seeds.seed(i as u64, out.episode[i], 8));
            assert_eq!(out.episode_length[i], 0);
            assert_eq!(out.episode_return[i], 0.0);
        } else {
            assert_eq!(
                o,
                &before_obs[i * ob..(i + 1) * ob],
                "env {i}: obs unchanged"
            );
            assert_eq!(out.episode[i], before.episode[i]);
            assert_eq!(out.seed[i], before.seed[i]);
            assert_eq!(out.episode_length[i], before.episode_length[i]);
            assert_eq!(out.episode_return[i], before.episode_return[i]);
        }
    }
    // Unmasked envs continue exactly as in the run without the partial reset; masked envs
    // diverge (they play another episode).
    let mut diverged = [false; 8];
    for (t, (ro, rr)) in reference.iter().enumerate() {
        let k = if t <= at as usize + 1 { t } else { t + 1 };
        let (o, r) = &run[k];
        for i in 0..8 {
            let same = ro[i * ob..(i + 1) * ob] == o[i * ob..(i + 1) * ob]
                && rr.reward[i] == r.reward[i]
                && rr.terminated[i] == r.terminated[i]
                && rr.truncated[i] == r.truncated[i]
                && rr.episode[i] == r.episode[i]
                && rr.seed[i] == r.seed[i]
                && rr.info[i * 2..i * 2 + 2] == r.info[i * 2..i * 2 + 2];
            if mask[i] {
                diverged[i] |= !same;
            } else {
                assert!(same, "unmasked env {i} differs at frame {t}");
            }
        }
    }
    for i in 0..8 {
        assert_eq!(diverged[i], mask[i], "env {i}");
    }
}

#[test]
fn partial_reset_is_deterministic_for_1_2_4_workers_and_copy_or_shared() {
    let mask = [true, false, false, true, false, true, true, false];
    let reference = masked_run(1, 25, Some((9, &mask)), false);
    for workers in [2, 4] {
        assert_eq!(
            masked_run(workers, 25, Some((9, &mask)), false),
            reference,
            "{workers} workers"
        );
    }
    assert_eq!(
        masked_run(2, 25, Some((9, &mask)), true),
        reference,
        "copying API"
    );
}

#[test]
fn partial_reset_needs_a_started_pool_and_a_full_mask() {
    let mut p = pool(config(EXE, test_env(), 4, 2));
    let mut out = BatchOutput::default();
    let m = [true, false, true, false];
    assert!(matches!(
        p.reset_envs(&m, &mut out),
        Err(PoolError::State(_))
    ));
    p.reset_shared(&mut out).unwrap();
    assert!(matches!(
        p.reset_envs(&m[..3], &mut out),
        Err(PoolError::BadBuffer { .. })
    ));
    p.reset_envs(&m, &mut out).unwrap();
    assert_eq!(out.episode, vec![1, 0, 1, 0]);
    p.reset_envs(&[false; 4], &mut out).unwrap();
    assert_eq!(out.episode, vec![1, 0, 1, 0]);
    p.step_shared(&[0; 4], &mut out).unwrap();
}
