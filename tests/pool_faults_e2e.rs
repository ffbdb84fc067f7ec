//! End-to-end tests of worker faults with real worker processes (the `e2e_worker` binary):
//! `kill -9` and `SIGSTOP` of a worker under both failure policies, an env that fails in its
//! worker, the restart budget, and a killed supervisor.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::Signal;
use rogue_gym_e2e::Copying;
use rogue_gym_e2e::*;
use rogue_gym_pool::{BatchOutput, EnvRegistry, FailurePolicy, Pool, PoolError, RecvWant};
use serde_json::json;

const EXE: &str = env!("CARGO_BIN_EXE_e2e_worker");

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
        let slot = p.reset_read(&mut out).unwrap();
        obs.copy_from_slice(p.shared_obs(slot));
    } else {
        p.reset_into(&mut obs, &mut out).unwrap();
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
            let slot = p.step_read(&actions, &mut out).unwrap();
            obs.copy_from_slice(p.shared_obs(slot));
        } else {
            p.step_into(&actions, &mut obs, &mut out).unwrap();
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
    p.reset_into(&mut obs, &mut out).unwrap();
    let victim = p.worker_pids()[1];
    signal(victim, Signal::SIGSTOP);
    let t0 = Instant::now();
    p.step_into(&[0, 1, 2, 3], &mut obs, &mut out).unwrap();
    assert!(t0.elapsed() >= Duration::from_millis(300));
    assert_eq!(out.restarted, vec![false, false, true, true]);
    assert_eq!(out.truncated[2..], [true, true]);
    assert!(!alive(victim), "the hung worker was killed");
    p.step_into(&[0, 1, 2, 3], &mut obs, &mut out).unwrap();
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
    p.reset_into(&mut obs, &mut out).unwrap();

    let victim = p.worker_pids()[0];
    signal(victim, Signal::SIGSTOP);
    let e = p.step_into(&[0, 1, 2, 3], &mut obs, &mut out).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, PoolError::WorkerFailed(_)), "{msg}");
    assert!(msg.contains(&format!("pid {victim}")), "{msg}");
    assert!(msg.contains("envs 0..2") && msg.contains("hung"), "{msg}");
    // The pool respawned the worker; it needs a reset.
    assert!(matches!(
        p.step_into(&[0, 1, 2, 3], &mut obs, &mut out),
        Err(PoolError::State(_))
    ));
    p.reset_into(&mut obs, &mut out).unwrap();
    p.step_into(&[0, 1, 2, 3], &mut obs, &mut out).unwrap();

    let victim = p.worker_pids()[1];
    signal(victim, Signal::SIGKILL);
    let e = p.step_into(&[0, 1, 2, 3], &mut obs, &mut out).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("signal 9 (SIGKILL)") && msg.contains("envs 2..4"),
        "{msg}"
    );
    p.reset_into(&mut obs, &mut out).unwrap();
    p.step_into(&[0, 1, 2, 3], &mut obs, &mut out).unwrap();
}

#[test]
fn env_failure_is_raised_with_its_env_and_message_and_reset_recovers() {
    let c = config(
        EXE,
        json!({"kind": "test", "obs_shape": [4], "fail_on_action": 3}),
        4,
        2,
    );
    let mut p = pool(c);
    let pids = p.worker_pids();
    let _guard = PidGuard(pids.clone());
    let mut obs = vec![0u8; 4 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset_into(&mut obs, &mut out).unwrap();
    let e = p.step_into(&[0, 1, 2, 3], &mut obs, &mut out).unwrap_err();
    let PoolError::EnvFailed { fault, worker, .. } = &e else {
        panic!("expected EnvFailed, got {e}");
    };
    assert_eq!((fault.env, *worker), (3, 1));
    let msg = e.to_string();
    assert!(msg.contains("injected failure on action 3"), "{msg}");
    assert!(msg.contains("env 3 failed in step (episode 0"), "{msg}");
    // The env failed, not its worker: no restart, and step needs a reset first.
    assert_eq!((p.worker_pids(), p.restarts()), (pids, 0));
    let e = p.step_into(&[0, 0, 0, 0], &mut obs, &mut out).unwrap_err();
    assert!(e.to_string().contains("call reset()"), "{e}");
    p.reset_into(&mut obs, &mut out).unwrap();
    p.step_into(&[0, 1, 2, 0], &mut obs, &mut out).unwrap();
    assert_eq!(out.episode_length, vec![1; 4]);
}

#[test]
fn a_worker_killed_between_answers_is_restarted_at_once_every_time() {
    // Each restarted worker answers before the next kill: no streak, no backoff (a storm of
    // external kills is not a worker that cannot start).
    let mut p = pool(config(EXE, test_env(), 2, 1));
    let _guard = PidGuard(p.worker_pids());
    let mut obs = vec![0u8; 2 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset_into(&mut obs, &mut out).unwrap();
    for _ in 0..3 {
        signal(p.worker_pids()[0], Signal::SIGKILL);
        p.step_into(&[0, 0], &mut obs, &mut out).unwrap();
        assert!(out.restarted.iter().all(|&r| r), "both envs were cut");
    }
    assert_eq!((p.restarts(), p.worker_deaths()), (3, 3));
}

/// Make every (re)start of the pool's workers fail (`e2e_worker`'s marker), or stop that.
#[test]
fn restart_budget_is_enforced() {
    let mut c = config(EXE, test_env(), 2, 1);
    c.max_restarts = 0;
    let mut p = pool(c);
    let _guard = PidGuard(p.worker_pids());
    let mut obs = vec![0u8; 2 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset_into(&mut obs, &mut out).unwrap();
    signal(p.worker_pids()[0], Signal::SIGKILL);
    let e = p.step_into(&[0, 0], &mut obs, &mut out).unwrap_err();
    assert!(matches!(e, PoolError::RestartBudgetExceeded { .. }), "{e}");
    assert!(e.to_string().contains("restart budget exhausted"));
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
fn async_mode_reports_restarted_envs() {
    let mut c = config(EXE, test_env(), 4, 2);
    c.batch_size = Some(2);
    let mut p = pool(c);
    let _guard = PidGuard(p.worker_pids());
    let restarted = |r: &rogue_gym_pool::Received| -> Vec<usize> {
        let mut v: Vec<usize> = r
            .env_ids
            .iter()
            .zip(&r.records)
            .filter(|(_, rec)| rec.restarted())
            .inspect(|(_, rec)| assert!(rec.truncated() && !rec.terminated()))
            .map(|(e, _)| *e)
            .collect();
        v.sort();
        v
    };
    p.async_reset().unwrap();
    p.recv_want(RecvWant::exactly(4)).unwrap();
    // Worker 0 (envs 0 and 1) dies while the caller holds all envs: its two envs restart.
    let old = p.worker_pids()[0];
    signal(old, Signal::SIGKILL);
    p.send(&[1; 4], &[0, 1, 2, 3]).unwrap();
    let mut got = Vec::new();
    for _ in 0..2 {
        got.extend(restarted(&p.recv().unwrap()));
    }
    got.sort();
    assert_eq!(got, vec![0, 1]);
    assert_eq!(p.restarts(), 1);
    // It dies again while env 0 was stepped alone and env 1 is with the caller: env 0's next
    // step restarts both, and env 1's next send hands over its restart at once.
    let pid = replacement(&p, 0, old);
    p.send(&[1], &[0]).unwrap();
    assert_eq!(p.recv_want(RecvWant::exactly(1)).unwrap().env_ids, vec![0]);
    signal(pid, Signal::SIGKILL);
    p.send(&[1], &[0]).unwrap();
    assert_eq!(
        restarted(&p.recv_want(RecvWant::exactly(1)).unwrap()),
        vec![0]
    );
    p.send(&[1], &[1]).unwrap();
    assert_eq!(
        restarted(&p.recv_want(RecvWant::exactly(1)).unwrap()),
        vec![1]
    );
    // From then on env 1 steps its new episode.
    p.send(&[1], &[1]).unwrap();
    let r = p.recv_want(RecvWant::exactly(1)).unwrap();
    assert!(!r.records[0].restarted());
    assert_eq!(r.records[0].episode_length, 1);
    assert_eq!(p.restarts(), 2);
}

#[test]
fn a_sync_call_hands_over_the_restart_of_an_env_the_caller_held() {
    let mut c = config(EXE, test_env(), 4, 2);
    c.batch_size = Some(2);
    let mut p = pool(c);
    let _guard = PidGuard(p.worker_pids());
    let mut out = BatchOutput::default();
    p.async_reset().unwrap();
    p.recv_want(RecvWant::exactly(4)).unwrap();
    // Worker 0 (envs 0 and 1) dies while env 0 is stepped alone and env 1 is with the caller:
    // env 0's next step restarts both; env 1's restart waits for the caller.
    let kill_worker_0 = |p: &mut Pool, old: u32| {
        p.send(&[1], &[0]).unwrap();
        assert_eq!(p.recv_want(RecvWant::exactly(1)).unwrap().env_ids, vec![0]);
        signal(old, Signal::SIGKILL);
        p.send(&[1], &[0]).unwrap();
        let r = p.recv_want(RecvWant::exactly(1)).unwrap();
        assert!(r.env_ids == [0] && r.records[0].restarted());
        replacement(p, 0, old)
    };
    let first = p.worker_pids()[0];
    let pid = kill_worker_0(&mut p, first);
    // A sync step hands env 1's restart over as its row (the new episode's first, its action
    // dropped), and steps the others.
    p.step_read(&[1; 4], &mut out).unwrap();
    assert_eq!(out.restarted, [false, true, false, false]);
    assert!(out.truncated[1] && !out.terminated[1] && out.reward[1] == 0.0);
    assert_eq!(out.episode_length, [1, 0, 1, 1]);
    // Nothing of it is left for env 1's next send: it steps its new episode.
    p.send(&[1], &[1]).unwrap();
    let r = p.recv_want(RecvWant::exactly(1)).unwrap();
    assert!(!r.records[0].restarted());
    assert_eq!(r.records[0].episode_length, 1);
    // The same for a partial reset that keeps env 1's episode; env 3, reset, starts afresh.
    kill_worker_0(&mut p, pid);
    p.partial_reset_read(&[false, false, false, true], &mut out)
        .unwrap();
    assert_eq!(out.restarted, [false, true, false, false]);
    assert_eq!(out.episode_length, [0, 0, 1, 0]);
    p.step_read(&[1; 4], &mut out).unwrap();
    assert_eq!(out.restarted, [false; 4]);
    assert_eq!(out.episode_length, [1, 1, 2, 1]);
    assert_eq!(p.restarts(), 2);
}

/// Wait until worker `k` has a pid other than `old` (its replacement was spawned).
fn replacement(p: &rogue_gym_pool::Pool, k: usize, old: u32) -> u32 {
    let t0 = Instant::now();
    loop {
        let pid = p.worker_pids()[k];
        if pid != old && pid != 0 {
            return pid;
        }
        assert!(t0.elapsed() < Duration::from_secs(5), "no replacement");
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn a_replacement_killed_while_it_starts_is_replaced_again_and_steps_go_on() {
    let mut c = config(EXE, test_env(), 4, 2);
    c.step_timeout = Some(Duration::from_secs(2));
    c.start_timeout = Duration::from_secs(5);
    let mut p = pool(c);
    let mut obs = vec![0u8; 4 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset_into(&mut obs, &mut out).unwrap();
    let first = p.worker_pids()[0];
    let mut guard = PidGuard(p.worker_pids());
    signal(first, Signal::SIGKILL);
    // This step sees the death and spawns a replacement (restarting); kill that one at once,
    // while it starts, from another thread: the next calls must still succeed in time.
    let t0 = Instant::now();
    p.step_into(&[0, 1, 2, 3], &mut obs, &mut out).unwrap();
    assert_eq!(out.restarted, vec![true, true, false, false]);
    let second = replacement(&p, 0, first);
    guard.0.push(second);
    signal(second, Signal::SIGKILL);
    for t in 0..5 {
        p.step_into(&[0, 1, 2, 3], &mut obs, &mut out).unwrap();
        if t == 0 {
            assert_eq!(
                out.restarted,
                vec![true, true, false, false],
                "the second loss"
            );
        }
    }
    assert!(
        t0.elapsed() < Duration::from_secs(5),
        "no call waited out a timeout"
    );
    assert_eq!(p.restarts(), 2, "both deaths count against the budget");
    let third = p.worker_pids()[0];
    guard.0.push(third);
    assert!(alive(third) && third != second);
    let id = p.id().clone();
    p.close().unwrap();
    assert!(pool_files_gone(&id));
}

#[test]
fn a_replacement_killed_while_restarting_under_raise_is_reported_and_one_reset_recovers() {
    let mut c = config(EXE, test_env(), 4, 2);
    c.on_worker_failure = FailurePolicy::Raise;
    let mut p = pool(c);
    let mut obs = vec![0u8; 4 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset_into(&mut obs, &mut out).unwrap();
    let first = p.worker_pids()[0];
    let mut guard = PidGuard(p.worker_pids());
    signal(first, Signal::SIGKILL);
    let e = p.step_into(&[0, 1, 2, 3], &mut obs, &mut out).unwrap_err();
    assert!(matches!(e, PoolError::WorkerFailed(_)), "{e}");
    let second = replacement(&p, 0, first);
    guard.0.push(second);
    signal(second, Signal::SIGKILL);
    // The reset finds the replacement dead while it starts: reported as a crash while
    // starting, and the pool is usable after the next reset.
    let e = p.reset_into(&mut obs, &mut out).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, PoolError::WorkerFailed(_)), "{msg}");
    assert!(
        msg.contains("while starting") && !msg.contains("(killed)"),
        "{msg}"
    );
    guard.0.push(p.worker_pids()[0]);
    p.reset_into(&mut obs, &mut out).unwrap();
    p.step_into(&[0, 1, 2, 3], &mut obs, &mut out).unwrap();
}

#[test]
fn a_storm_of_kills_and_stops_never_bricks_the_pool() {
    // Random SIGKILLs (and a SIGSTOP now and then) of workers, restarting ones included,
    // every ~100-300 ms for ~4 s, under the restart policy: every step succeeds.
    let mut c = config(EXE, test_env(), 8, 4);
    c.step_timeout = Some(Duration::from_millis(500));
    c.start_timeout = Duration::from_secs(2);
    c.max_restarts = 1000;
    let mut p = pool(c);
    let mut obs = vec![0u8; 8 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset_into(&mut obs, &mut out).unwrap();
    let mut guard = PidGuard(Vec::new());
    let mut rng = 0x1234_5678u64;
    let mut next = |n: u64| {
        rng = rogue_gym_pool::seeds::splitmix(rng);
        rng % n
    };
    let t0 = Instant::now();
    let mut last_kill = Instant::now();
    let (mut steps, mut flagged, mut kills) = (0u64, 0usize, 0u32);
    while t0.elapsed() < Duration::from_secs(4) {
        if last_kill.elapsed() > Duration::from_millis(100 + next(200)) {
            let pids = p.worker_pids();
            let victim = pids[next(pids.len() as u64) as usize];
            guard.0.push(victim);
            let sig = if next(5) == 0 {
                Signal::SIGSTOP
            } else {
                Signal::SIGKILL
            };
            if alive(victim) {
                let _ = nix::sys::signal::kill(nix::unistd::Pid::from_raw(victim as i32), sig);
                kills += 1;
            }
            last_kill = Instant::now();
        }
        let actions: Vec<i64> = (0..8).map(|i| action(i, steps, 5)).collect();
        let s = Instant::now();
        p.step_into(&actions, &mut obs, &mut out)
            .expect("steps go on through the storm");
        assert!(
            s.elapsed() < Duration::from_secs(4),
            "a step outlived its bounds"
        );
        flagged += out.restarted.iter().filter(|&&r| r).count();
        steps += 1;
    }
    assert!(kills >= 8, "{kills} signals sent");
    assert!(flagged > 0 && p.restarts() > 0, "restarts are flagged");
    // After the storm: the pool steps normally.
    for t in 0..20 {
        let actions: Vec<i64> = (0..8).map(|i| action(i, t, 5)).collect();
        p.step_into(&actions, &mut obs, &mut out).unwrap();
    }
    guard.0.extend(p.worker_pids());
    let id = p.id().clone();
    p.close().unwrap();
    assert!(pool_files_gone(&id), "nothing leaks");
}

/// Pids of this process's live children whose command line contains `mark` (the workers of
/// one pool, by its runtime directory: other tests' pools run in this process too).
fn children_running(mark: &str) -> Vec<u32> {
    let me = std::process::id();
    let mut out = Vec::new();
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
            continue;
        };
        let ppid = stat
            .rsplit_once(')')
            .and_then(|(_, r)| r.split_whitespace().nth(1))
            .and_then(|p| p.parse::<u32>().ok());
        let cmd = std::fs::read(format!("/proc/{pid}/cmdline")).unwrap_or_default();
        let has_mark = cmd.windows(mark.len()).any(|w| w == mark.as_bytes());
        if ppid == Some(me) && has_mark && alive(pid) {
            out.push(pid);
        }
    }
    out
}

#[test]
fn a_worker_killed_during_the_pools_start_is_restarted_or_reported() {
    let base = test_base().join("startkill");
    let _sweep = SweepGuard(base.clone());
    let mark = base.display().to_string();
    for policy in [FailurePolicy::Restart, FailurePolicy::Raise] {
        // A killer thread SIGKILLs the first worker it sees while the pool starts.
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let killer = {
            let stop = stop.clone();
            let mark = mark.clone();
            std::thread::spawn(move || {
                let t0 = Instant::now();
                while !stop.load(std::sync::atomic::Ordering::Relaxed)
                    && t0.elapsed() < Duration::from_secs(10)
                {
                    if let Some(&pid) = children_running(&mark).first() {
                        signal(pid, Signal::SIGKILL);
                        return Some(pid);
                    }
                    std::thread::sleep(Duration::from_micros(200));
                }
                None
            })
        };
        let mut c = config(EXE, test_env(), 4, 2);
        c.on_worker_failure = policy;
        c.start_timeout = Duration::from_secs(5);
        c.runtime_dir = Some(base.clone());
        let t0 = Instant::now();
        let made = Pool::new(c, &EnvRegistry::with_defaults());
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        let killed = killer.join().unwrap().expect("a worker was seen starting");
        assert!(
            t0.elapsed() < Duration::from_secs(5),
            "no start-up waited out a timeout"
        );
        match (policy, made) {
            (FailurePolicy::Restart, Ok(mut p)) => {
                let _g = PidGuard(p.worker_pids());
                assert_eq!(p.restarts(), 1);
                assert!(!p.worker_pids().contains(&killed));
                run_sync(&mut p, 5).unwrap();
            }
            (FailurePolicy::Raise, Err(e)) => {
                let msg = e.to_string();
                assert!(matches!(e, PoolError::WorkerFailed(_)), "{msg}");
                assert!(
                    msg.contains(&format!("pid {killed}")) && msg.contains("SIGKILL"),
                    "{msg}"
                );
            }
            (policy, made) => panic!("{policy:?}: unexpected {:?}", made.map(|_| ())),
        }
    }
}

#[test]
fn a_worker_killed_just_before_close_is_no_error_and_nothing_leaks() {
    let mut p = pool(config(EXE, test_env(), 4, 2));
    let _g = PidGuard(p.worker_pids());
    let mut obs = vec![0u8; 4 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset_into(&mut obs, &mut out).unwrap();
    let pids = p.worker_pids();
    signal(pids[1], Signal::SIGKILL);
    let id = p.id().clone();
    let t0 = Instant::now();
    p.close().unwrap();
    assert!(t0.elapsed() < Duration::from_secs(1));
    assert!(pids.iter().all(|&w| !alive(w)));
    assert!(pool_files_gone(&id));
}

#[test]
fn an_env_failing_in_an_async_step_of_part_of_a_block_is_raised_and_an_async_reset_recovers() {
    let env = json!({"kind": "test", "obs_shape": [4], "fail_on_action": 3});
    let mut c = config(EXE, env, 4, 2);
    c.batch_size = Some(1);
    let mut p = pool(c);
    p.async_reset().unwrap();
    p.recv_want(RecvWant::exactly(4)).unwrap();
    // Env 1 alone (its worker also hosts env 0) fails; env 2 steps fine.
    p.send(&[3, 0], &[1, 2]).unwrap();
    let mut outcome = Ok(());
    for _ in 0..2 {
        // The failure surfaces at the first call that sees it, a recv (or a later send).
        match p.recv_want(RecvWant::exactly(1)) {
            Ok(r) => assert_eq!(r.env_ids, vec![2]),
            Err(e) => {
                outcome = Err(e);
                break;
            }
        }
    }
    let e = outcome.unwrap_err();
    assert!(
        matches!(&e, PoolError::EnvFailed { fault, .. } if fault.env == 1 && fault.message.contains("injected failure")),
        "{e}"
    );
    let e = p.send(&[0], &[0]).unwrap_err();
    assert!(e.to_string().contains("async_reset()"), "{e}");
    p.async_reset().unwrap();
    let r = p.recv_want(RecvWant::exactly(4)).unwrap();
    let mut ids = r.env_ids.clone();
    ids.sort();
    assert_eq!(ids, vec![0, 1, 2, 3]);
    p.send(&[0], &[1]).unwrap();
    assert_eq!(p.recv_want(RecvWant::exactly(1)).unwrap().env_ids, vec![1]);
}
