//! End-to-end tests of the pool with real worker processes (the `e2e_worker` binary) hosting
//! the deterministic test env: determinism, seeds, zero-copy blocks, partial resets, cleanup and
//! errors. Worker faults (kills, hangs, budgets) are in `pool_faults_e2e.rs`, planned
//! replacements in `pool_recycling_e2e.rs`.

use std::time::Duration;

use rogue_gym_e2e::Copying;
use rogue_gym_e2e::*;
use rogue_gym_pool::{BatchOutput, EnvRegistry, Pool, PoolError, RecvWant, SeedPolicy, SeedSet};
use serde_json::json;

const EXE: &str = env!("CARGO_BIN_EXE_e2e_worker");

#[test]
fn trajectories_identical_for_any_worker_count_even_or_not_and_sync_async() {
    let steps = 40;
    let mut reference = None;
    for workers in [1, 2, 3, 4, 5, 8] {
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
    for workers in [1, 2, 3, 4, 7, 8] {
        let mut p = pool(config(EXE, test_env(), 8, workers));
        let d = run_sync_shared(&mut p, steps).unwrap();
        assert_eq!(
            d, reference,
            "shared-slot sync with {workers} workers differs"
        );
    }
    for (workers, batch) in [(4, 4), (2, 4), (4, 8), (8, 1), (8, 4), (3, 8), (5, 8)] {
        for views in [false, true] {
            let mut c = config(EXE, test_env(), 8, workers);
            c.batch_size = Some(batch);
            let mut p = pool(c);
            p.set_async_views(views);
            let d = run_async(&mut p, steps).unwrap();
            assert_eq!(
                d, reference,
                "async with {workers} workers, batch {batch} (views: {views}) differs"
            );
        }
    }
}

#[test]
fn async_views_stay_put_while_their_envs_step_again() {
    // Two halves of 8 envs on 2 workers: each recv is one worker's block, written in place.
    let mut c = config(EXE, test_env(), 8, 2);
    c.batch_size = Some(4);
    let mut p = pool(c);
    p.set_async_views(true);
    let ob = p.obs_bytes();
    p.async_reset().unwrap();
    let mut views = 0;
    let mut held: Option<(usize, usize, Vec<u8>)> = None;
    for t in 0..40 {
        let got = p.recv().unwrap();
        if let Some((slot, first)) = got.view {
            views += 1;
            assert_eq!(got.env_ids, (first..first + 4).collect::<Vec<_>>());
            assert!(
                got.records.is_empty(),
                "a view's records are read in its slot"
            );
            let mut out = BatchOutput::default();
            p.read_rows(&got, None, &mut out).unwrap();
            assert_eq!(out.env_ids, got.env_ids, "read where the view says");
            held = Some((
                slot,
                first,
                p.shared_obs(slot)[first * ob..(first + 4) * ob].to_vec(),
            ));
        }
        let ids = got.env_ids.clone();
        p.send(&vec![(t % 3) as i64; ids.len()], &ids).unwrap();
        // The view is unchanged after the send, while the worker steps those envs again.
        if let Some((slot, first, snapshot)) = &held {
            std::thread::sleep(std::time::Duration::from_millis(1));
            assert!(p.shared_obs(*slot)[first * ob..(first + 4) * ob] == snapshot[..]);
        }
    }
    assert!(
        views >= 36,
        "{views} of 40 recvs were views (all but the reset's)"
    );
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
    a.reset_into(&mut obs, &mut out).unwrap();
    let mut seen_final = false;
    for _ in 0..13 {
        a.step_into(&[1, 1, 1, 1], &mut obs, &mut out).unwrap();
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
    p.reset_into(&mut obs, &mut out).unwrap();
    assert_eq!(out.seed, vec![1000, 1001, 1002, 1003]);
    p.reset_into(&mut obs, &mut out).unwrap();
    assert_eq!(out.seed, vec![1004, 1005, 1006, 1007]);
    assert_eq!(out.episode, vec![1, 1, 1, 1]);
}

#[test]
fn bad_input_is_an_error_value() {
    let mut p = pool(config(EXE, test_env(), 4, 2));
    let mut obs = vec![0u8; 4 * p.obs_bytes()];
    let mut out = BatchOutput::default();
    let e = p.step_into(&[0, 0, 0, 0], &mut obs, &mut out).unwrap_err();
    assert!(e.to_string().contains("reset()"), "{e}");
    p.reset_into(&mut obs, &mut out).unwrap();
    let e = p.step_into(&[0, 0, 0], &mut obs, &mut out).unwrap_err();
    assert_eq!(
        e.to_string(),
        "got 3 actions for 4 envs: pass exactly one action per env"
    );
    let e = p.step_into(&[0, 0, 7, 0], &mut obs, &mut out).unwrap_err();
    assert_eq!(
        e.to_string(),
        "env 2: action 7 is out of range; valid actions are 0 to 4 (range(5))"
    );
    let a = p.step(&[0; 4]).unwrap();
    let e = p.read_rows(&a, Some(&mut obs[1..]), &mut out).unwrap_err();
    assert!(matches!(e, PoolError::BadBuffer { .. }));
    // Async misuse.
    let e = p.send(&[0, 0], &[1, 1]).unwrap_err();
    assert!(e.to_string().contains("env 1 appears twice"), "{e}");
    let e = p.send(&[0], &[9]).unwrap_err();
    assert!(e.to_string().contains("envs 0 to 3"), "{e}");
    let e = p.recv().unwrap_err();
    assert!(e.to_string().contains("send()"), "{e}");
    // Between the halves of a whole-batch call, the async API is refused and the call stands.
    p.send_step(&[0; 4]).unwrap();
    for e in [p.recv().unwrap_err(), p.send(&[0], &[1]).unwrap_err()] {
        assert!(e.to_string().contains("wait() for it"), "{e}");
    }
    let a = p
        .wait(Some(Duration::from_secs(10)))
        .unwrap()
        .expect("the step is answered");
    assert_eq!(a.env_ids, [0, 1, 2, 3], "every env, in env order");
    // The pool still works.
    p.step_into(&[0, 1, 2, 3], &mut obs, &mut out).unwrap();

    // Config errors.
    let reg = EnvRegistry::with_defaults();
    let e = Pool::new(config(EXE, test_env(), 2, 3), &reg).unwrap_err();
    assert!(e.to_string().contains("must not exceed num_envs"), "{e}");
    let mut c = config(EXE, test_env(), 5, 2);
    c.batch_size = Some(6);
    let e = Pool::new(c, &reg).unwrap_err();
    assert!(e.to_string().contains("between 1 and num_envs (5)"), "{e}");
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
fn async_serves_envs_one_by_one_any_batch_size_any_subset() {
    // 5 envs on 2 workers (blocks of 3 and 2), batches of 3: not a whole number of blocks.
    let mut c = config(EXE, test_env(), 5, 2);
    c.batch_size = Some(3);
    let mut p = pool(c);
    p.async_reset().unwrap();
    let r1 = p.recv().unwrap();
    assert_eq!(r1.env_ids.len(), 3);
    assert_eq!(r1.obs.len(), 3 * p.obs_bytes());
    let r2 = p.recv_want(RecvWant::exactly(2)).unwrap();
    let mut ids = [r1.env_ids.clone(), r2.env_ids.clone()].concat();
    ids.sort();
    assert_eq!(ids, vec![0, 1, 2, 3, 4]);
    // One env of the first worker, alone; another one while it is in flight.
    p.send(&[1], &[0]).unwrap();
    let e = p.send(&[1], &[0]).unwrap_err();
    assert!(e.to_string().contains("env 0 is in flight"), "{e}");
    p.send(&[2], &[2]).unwrap();
    let mut got = Vec::new();
    while got.len() < 2 {
        got.extend(p.recv_want(RecvWant::exactly(1)).unwrap().env_ids);
    }
    got.sort();
    assert_eq!(got, vec![0, 2]);
    // Nothing outstanding: recv says what to do; a deadline with nothing ready times out.
    let e = p.recv_want(RecvWant::exactly(1)).unwrap_err();
    assert!(e.to_string().contains("send()"), "{e}");
    p.send(&[0], &[4]).unwrap();
    let r = p
        .recv_want(RecvWant {
            min_batch: 1,
            max_batch: 5,
            timeout: Some(Duration::from_secs(5)),
        })
        .unwrap();
    assert_eq!(r.env_ids, vec![4], "returns once every env sent is ready");
    let id = p.id().clone();
    p.close().unwrap();
    assert!(pool_files_gone(&id));
    // What recv handed over is the caller's own.
    assert_eq!(r1.obs.len(), 3 * 3 * 5 * 7);
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
fn shared_slots_stay_mapped_through_their_arc_after_close() {
    let mut p = pool(config(EXE, test_env(), 4, 2));
    let mut out = BatchOutput::default();
    let slot = p.reset_read(&mut out).unwrap();
    let snapshot = p.shared_obs(slot).to_vec();
    let buf = p.shared_buffer().unwrap();
    let offset = slot * p.slot_layout().bytes();
    let id = p.id().clone();
    p.close().unwrap();
    assert!(pool_files_gone(&id));
    assert!(p.slot_rows(slot).is_none() && p.shared_obs(slot).is_empty());
    // SAFETY: the Arc keeps the mapping alive; the range lies inside it.
    let view = unsafe { std::slice::from_raw_parts(buf.as_ptr().add(offset), snapshot.len()) };
    assert_eq!(view, &snapshot[..]);
}

#[test]
fn select_slot_steers_the_next_shared_batch_and_leaves_the_others_alone() {
    let mut c = config(EXE, test_env(), 4, 2);
    c.batch_slots = 4;
    let mut p = pool(c);
    assert_eq!(p.batch_slots(), 4);
    let mut out = BatchOutput::default();
    assert_eq!(p.reset_read(&mut out).unwrap(), 0);
    let kept = p.shared_obs(0).to_vec();
    // The slots take turns, and a selected slot is written next; slot 0 is never touched.
    assert_eq!(p.step_read(&[1; 4], &mut out).unwrap(), 1);
    p.select_slot(3).unwrap();
    assert_eq!(p.step_read(&[2; 4], &mut out).unwrap(), 3);
    p.select_slot(1).unwrap();
    assert_eq!(p.step_read(&[3; 4], &mut out).unwrap(), 1);
    assert_eq!(p.step_read(&[4; 4], &mut out).unwrap(), 2);
    assert_eq!(
        p.shared_obs(0),
        &kept[..],
        "a slot no call named stays as it was"
    );
    let err = p.select_slot(4).unwrap_err().to_string();
    assert!(err.contains("4 batch slots"), "{err}");
    for bad in [1, rogue_gym_pool::MAX_BATCH_SLOTS + 1] {
        let mut c = config(EXE, test_env(), 4, 2);
        c.batch_slots = bad;
        let err = Pool::new(c, &EnvRegistry::with_defaults()).unwrap_err();
        assert!(err.to_string().contains("batch_slots"), "{err}");
    }
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
        p.step_into(&[0; 4], &mut obs, &mut out).is_err(),
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
        p.reset_into(&mut obs, &mut out).unwrap();
        grab(&p, None, &obs, &out);
    } else {
        let s = p.reset_read(&mut out).unwrap();
        grab(&p, Some(s), &obs, &out);
    }
    for t in 0..steps {
        let actions: Vec<i64> = (0..n).map(|i| action(i, t, 5)).collect();
        if copy {
            p.step_into(&actions, &mut obs, &mut out).unwrap();
            grab(&p, None, &obs, &out);
        } else {
            let s = p.step_read(&actions, &mut out).unwrap();
            grab(&p, Some(s), &obs, &out);
        }
        if let Some((at, m)) = mask
            && at == t
        {
            if copy {
                p.partial_reset_into(m, &mut obs, &mut out).unwrap();
                grab(&p, None, &obs, &out);
            } else {
                let s = p.partial_reset_read(m, &mut out).unwrap();
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
        p.partial_reset_read(&m, &mut out),
        Err(PoolError::State(_))
    ));
    p.reset_read(&mut out).unwrap();
    assert!(matches!(
        p.partial_reset_read(&m[..3], &mut out),
        Err(PoolError::BadBuffer { .. })
    ));
    p.partial_reset_read(&m, &mut out).unwrap();
    assert_eq!(out.episode, vec![1, 0, 1, 0]);
    p.partial_reset_read(&[false; 4], &mut out).unwrap();
    assert_eq!(out.episode, vec![1, 0, 1, 0]);
    // Its halves, as a full reset's: sent, then waited for.
    let slot = p.send_reset(Some(&[false, true, false, false])).unwrap();
    let a = p
        .wait(Some(Duration::from_secs(10)))
        .unwrap()
        .expect("answered");
    assert_eq!(a.slot(), Some(slot));
    p.read_rows(&a, None, &mut out).unwrap();
    assert_eq!(out.episode, vec![1, 1, 1, 0]);
    p.step_read(&[0; 4], &mut out).unwrap();
}

#[test]
fn action_extras_reach_their_envs_with_the_step_even_by_send() {
    // 5 envs on 2 workers: blocks 0..3 and 3..5.
    let mut p = pool(config(EXE, test_env(), 5, 2));
    let mut out = BatchOutput::default();
    let extra =
        |p: &mut Pool, env: usize| p.call_envs(&[(env, b"x".to_vec())]).unwrap()[0].1.clone();
    p.reset_read(&mut out).unwrap();
    p.stage_action_extras(&[(1, b"one".to_vec()), (4, b"four".to_vec())])
        .unwrap();
    p.step_read(&[0; 5], &mut out).unwrap();
    assert_eq!(extra(&mut p, 1), b"one");
    assert_eq!(extra(&mut p, 4), b"four");
    assert_eq!(extra(&mut p, 0), b"");
    // A reset drops what is staged; the next step carries nothing.
    p.stage_action_extras(&[(0, b"zero".to_vec())]).unwrap();
    p.reset_read(&mut out).unwrap();
    p.step_read(&[0; 5], &mut out).unwrap();
    assert_eq!(extra(&mut p, 0), b"");
    // EnvPool-style: one worker's envs at a time, each send with its own staged extras.
    p.stage_action_extras(&[(3, b"three".to_vec())]).unwrap();
    p.send(&[0, 0], &[3, 4]).unwrap();
    p.stage_action_extras(&[(1, b"uno".to_vec())]).unwrap();
    p.send(&[0, 0, 0], &[0, 1, 2]).unwrap();
    p.recv().unwrap();
    assert_eq!(extra(&mut p, 3), b"three");
    assert_eq!(extra(&mut p, 1), b"uno");
    // An env that refuses its extra fails the step, naming it; a reset recovers.
    p.stage_action_extras(&[(2, b"bad".to_vec())]).unwrap();
    let e = p.step_read(&[0; 5], &mut out).unwrap_err();
    assert!(
        matches!(&e, PoolError::EnvFailed { fault, .. } if fault.env == 2),
        "{e}"
    );
    assert!(e.to_string().contains("a bad action extra"), "{e}");
    let e = p.stage_action_extras(&[(7, b"x".to_vec())]).unwrap_err();
    assert!(e.to_string().contains("env 7 does not exist"), "{e}");
    p.reset_read(&mut out).unwrap();
    p.step_read(&[0; 5], &mut out).unwrap();
}

#[test]
fn a_refused_action_extra_leaves_no_env_busy_in_a_worker_whose_envs_run_on_threads() {
    // The step fails before any env thread starts; the envs it named must be free for the
    // reset after it, which a worker that kept them busy would hold until `step_timeout`
    // (and the pool would then kill it as hung).
    let mut c = config(EXE, test_env(), 4, 2);
    c.env_threads = 2;
    c.step_timeout = Some(Duration::from_secs(3));
    let mut p = pool(c);
    let mut out = BatchOutput::default();
    p.reset_read(&mut out).unwrap();
    p.stage_action_extras(&[(1, b"bad".to_vec())]).unwrap();
    let e = p.step_read(&[0; 4], &mut out).unwrap_err();
    assert!(
        matches!(&e, PoolError::EnvFailed { fault, .. } if fault.env == 1),
        "{e}"
    );
    p.reset_read(&mut out).unwrap();
    p.step_read(&[0; 4], &mut out).unwrap();
    assert_eq!(
        (p.restarts(), p.worker_deaths()),
        (0, 0),
        "no worker was hung"
    );
    assert!(out.episode_length.iter().all(|&l| l == 1));
}

#[test]
fn env_calls_reach_the_chosen_envs_in_order_and_errors_name_the_env() {
    // 5 envs on 2 workers: blocks 0..3 and 3..5.
    let mut p = pool(config(EXE, test_env(), 5, 2));
    let mut out = BatchOutput::default();
    // Before any reset: the envs exist.
    let r = p.call_envs(&[(4, b"t".to_vec())]).unwrap();
    assert_eq!(r, vec![(4, 0u32.to_le_bytes().to_vec())]);
    p.reset_read(&mut out).unwrap();
    for _ in 0..3 {
        p.step_read(&[0; 5], &mut out).unwrap();
    }
    let t = |env: usize| out.episode_length[env];
    let r = p
        .call_envs(&[(4, b"t".to_vec()), (0, b"t".to_vec()), (3, b"t".to_vec())])
        .unwrap();
    let got: Vec<(usize, u32)> = r
        .iter()
        .map(|(e, b)| (*e, u32::from_le_bytes(b[..4].try_into().unwrap())))
        .collect();
    assert_eq!(got, vec![(4, t(4)), (0, t(0)), (3, t(3))]);
    let e = p.call_envs(&[(1, b"nope".to_vec())]).unwrap_err();
    assert!(
        matches!(&e, PoolError::EnvFailed { fault, .. } if fault.env == 1),
        "{e}"
    );
    assert!(e.to_string().contains("unknown call"), "{e}");
    let e = p.call_envs(&[(9, b"t".to_vec())]).unwrap_err();
    assert!(e.to_string().contains("env 9 does not exist"), "{e}");
    p.reset_read(&mut out).unwrap();
    p.step_read(&[0; 5], &mut out).unwrap();
}
