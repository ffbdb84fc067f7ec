//! Every call keeps its bound while workers cannot come back: a worker that dies at every
//! start makes steps, resets, `recv` and calls raise within `step_timeout + start_timeout`,
//! spends the restart budget and says so, and dead workers come back side by side.

use std::time::{Duration, Instant};

use nix::sys::signal::Signal;
use rogue_gym_e2e::Copying;
use rogue_gym_e2e::*;
use rogue_gym_pool::{BatchOutput, PoolError};

const EXE: &str = env!("CARGO_BIN_EXE_e2e_worker");

fn die_at_start(p: &rogue_gym_pool::Pool, on: bool) {
    die_at_start_marker(p, "die-at-start", on)
}

fn die_at_start_marker(p: &rogue_gym_pool::Pool, name: &str, on: bool) {
    let marker = p.id().aux_dir().join(name);
    if on {
        std::fs::write(&marker, b"").unwrap();
    } else {
        std::fs::remove_file(&marker).unwrap();
    }
}

#[test]
fn a_worker_that_dies_at_every_start_makes_the_call_raise_within_its_bound() {
    // Worker 1 dies at every restart (with growing backoffs). The step raises NotBackInTime
    // within step_timeout + start_timeout, naming the worker; once it can start, one reset
    // recovers and every env steps again.
    let mut c = config(EXE, test_env(), 4, 2);
    c.step_timeout = Some(Duration::from_millis(300));
    c.start_timeout = Duration::from_millis(1200);
    let mut p = pool(c);
    let bound = p.call_bound().unwrap();
    assert_eq!(bound, Duration::from_millis(1500));
    let mut guard = PidGuard(p.worker_pids());
    let mut obs = vec![0u8; 4 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset_into(&mut obs, &mut out).unwrap();
    die_at_start(&p, true);
    signal(p.worker_pids()[1], Signal::SIGKILL);
    let t0 = Instant::now();
    let e = p.step_into(&[0; 4], &mut obs, &mut out).unwrap_err();
    let took = t0.elapsed();
    assert!(
        took <= bound,
        "the call took {took:?}, over its bound {bound:?}"
    );
    assert!(
        took >= Duration::from_millis(1000),
        "it tried until near its bound: {took:?}"
    );
    let PoolError::NotBackInTime {
        waiting, deaths, ..
    } = &e
    else {
        panic!("expected NotBackInTime, got {e}");
    };
    assert_eq!(waiting.iter().map(|w| w.0).collect::<Vec<_>>(), [1], "{e}");
    // 0, 50, 100, 200 ms backoffs (capped at start_timeout / 2) between quick deaths.
    assert!(*deaths >= 4 && *deaths == p.worker_deaths(), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("worker 1 (") && msg.contains("call reset() to continue"),
        "{msg}"
    );
    assert!(msg.contains("exited with code 3 while starting"), "{msg}");
    // Still dying: the reset raises within the same bound.
    let t0 = Instant::now();
    assert!(matches!(
        p.reset_into(&mut obs, &mut out),
        Err(PoolError::NotBackInTime { .. })
    ));
    assert!(t0.elapsed() <= bound);
    die_at_start(&p, false);
    p.reset_into(&mut obs, &mut out).unwrap();
    for t in 0..5 {
        let actions: Vec<i64> = (0..4).map(|i| action(i, t, 5)).collect();
        p.step_into(&actions, &mut obs, &mut out).unwrap();
        assert!(!out.restarted.iter().any(|&r| r));
    }
    guard.0.extend(p.worker_pids());
}

#[test]
fn dead_workers_come_back_side_by_side() {
    // Worker 0 dies at every start and waits out ever longer backoffs (up to 800 ms); worker 1,
    // killed meanwhile while idle (its block of the step already taken), is back at once, not
    // after worker 0's backoff. Only worker 0 is reported.
    let mut c = config(EXE, test_env(), 6, 3);
    c.step_timeout = Some(Duration::from_millis(300));
    c.start_timeout = Duration::from_millis(1600);
    let mut p = pool(c);
    let mut guard = PidGuard(p.worker_pids());
    let mut obs = vec![0u8; 6 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset_into(&mut obs, &mut out).unwrap();
    die_at_start_marker(&p, "die-at-start.0", true);
    signal(p.worker_pids()[0], Signal::SIGKILL);
    let pids = p.pids_handle();
    let killer = std::thread::spawn(move || {
        use std::sync::atomic::Ordering::Relaxed;
        std::thread::sleep(Duration::from_millis(700));
        let old = pids[1].load(Relaxed);
        signal(old, Signal::SIGKILL);
        let t0 = Instant::now();
        while pids[1].load(Relaxed) == old && t0.elapsed() < Duration::from_secs(3) {
            std::thread::sleep(Duration::from_millis(2));
        }
        (t0.elapsed(), pids[1].load(Relaxed))
    });
    let e = p.step_into(&[0; 6], &mut obs, &mut out).unwrap_err();
    let (back_after, new_pid) = killer.join().unwrap();
    guard.0.push(new_pid);
    assert!(
        back_after < Duration::from_millis(300),
        "worker 1 came back after {back_after:?}: it waited for worker 0's backoff"
    );
    assert!(alive(new_pid), "its replacement runs");
    let PoolError::NotBackInTime { waiting, .. } = &e else {
        panic!("expected NotBackInTime, got {e}");
    };
    assert_eq!(waiting.iter().map(|w| w.0).collect::<Vec<_>>(), [0], "{e}");
    die_at_start_marker(&p, "die-at-start.0", false);
    p.reset_into(&mut obs, &mut out).unwrap();
    p.step_into(&[0; 6], &mut obs, &mut out).unwrap();
    assert!(
        !out.restarted.iter().any(|&r| r),
        "a reset starts every env afresh"
    );
    guard.0.extend(p.worker_pids());
}

#[test]
fn recv_and_calls_keep_their_bound_when_a_worker_dies_at_every_start() {
    // The async API (send + recv) and env calls wait for the same lost worker as a step does:
    // each raises within step_timeout + start_timeout, and one reset recovers afterwards.
    let mut c = config(EXE, test_env(), 4, 2);
    c.batch_size = Some(2);
    c.step_timeout = Some(Duration::from_millis(300));
    c.start_timeout = Duration::from_millis(900);
    let mut p = pool(c);
    let bound = p.call_bound().unwrap();
    let mut guard = PidGuard(p.worker_pids());
    p.async_reset().unwrap();
    let (b0, b1) = (p.recv().unwrap(), p.recv().unwrap());
    let (ids0, ids1) = (b0.env_ids.clone(), b1.env_ids.clone());
    drop((b0, b1));
    die_at_start(&p, true);
    signal(p.worker_pids()[1], Signal::SIGKILL);
    p.send(&[1, 1], &ids0).unwrap();
    p.send(&[1, 1], &ids1).unwrap();
    let t0 = Instant::now();
    let mut outcome = Ok(());
    for _ in 0..2 {
        if let Err(e) = p.recv() {
            outcome = Err(e);
            break;
        }
    }
    assert!(t0.elapsed() <= bound, "recv took {:?}", t0.elapsed());
    assert!(
        matches!(outcome, Err(PoolError::NotBackInTime { .. })),
        "{outcome:?}"
    );
    // An env call needs every worker idle: it waits for the lost one within the same bound.
    let t0 = Instant::now();
    let e = p.call_envs(&[(0, b"t".to_vec())]).unwrap_err();
    assert!(t0.elapsed() <= bound, "the call took {:?}", t0.elapsed());
    assert!(matches!(e, PoolError::NotBackInTime { .. }), "{e}");
    die_at_start(&p, false);
    let mut obs = vec![0u8; 4 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset_into(&mut obs, &mut out).unwrap();
    assert_eq!(p.call_envs(&[(3, b"t".to_vec())]).unwrap().len(), 1);
    guard.0.extend(p.worker_pids());
}

#[test]
fn a_worker_that_dies_at_every_start_spends_the_budget_and_says_so() {
    let mut c = config(EXE, test_env(), 4, 2);
    c.step_timeout = Some(Duration::from_millis(300));
    c.start_timeout = Duration::from_secs(5);
    c.max_restarts = 3;
    let mut p = pool(c);
    let mut guard = PidGuard(p.worker_pids());
    let mut obs = vec![0u8; 4 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    p.reset_into(&mut obs, &mut out).unwrap();
    die_at_start(&p, true);
    signal(p.worker_pids()[0], Signal::SIGKILL);
    let t0 = Instant::now();
    let e = p.step_into(&[0; 4], &mut obs, &mut out).unwrap_err();
    assert!(
        t0.elapsed() < Duration::from_secs(2),
        "the budget ends it early"
    );
    assert!(
        matches!(
            e,
            PoolError::RestartBudgetExceeded {
                max_restarts: 3,
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string()
            .contains("restart budget exhausted (3 restarts)"),
        "{e}"
    );
    // A spent budget stays spent.
    die_at_start(&p, false);
    assert!(matches!(
        p.reset_into(&mut obs, &mut out),
        Err(PoolError::RestartBudgetExceeded { .. })
    ));
    guard.0.extend(p.worker_pids());
}
