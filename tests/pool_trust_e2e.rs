//! End-to-end tests of what the caller trusts of its workers: a worker that writes a value out
//! of its bounds into shared memory (a size beyond the room, an info row outside its block, an
//! episode index no env reaches, a flag byte that is no bool), is killed half-way through an
//! answer, or tries to resize the pool's buffer. Each is named in an error or restarted (per
//! the failure policy), never believed; the pool steps again after a reset; nothing is left.

use rogue_gym_e2e::*;
use rogue_gym_pool::wire::sabotage::{Misdeed, Sabotage};
use rogue_gym_pool::{FailurePolicy, PoolConfig, PoolError};

const EXE: &str = env!("CARGO_BIN_EXE_e2e_worker");

/// 4 test envs on 2 workers, worker 1 committing `what` in its `at`-th reset or step.
fn sabotaged(what: Misdeed, at: u64, policy: FailurePolicy) -> PoolConfig {
    let mut c = config(EXE, test_env(), 4, 2);
    c.on_worker_failure = policy;
    c.sabotage = Some(Sabotage {
        worker: 1,
        at,
        what,
    });
    c
}

/// Step worker 1's sabotaged answer (its 3rd command: reset, step, step) under `policy`; the
/// result of that step, then whether a reset and a step work after it.
fn third_answer(
    what: Misdeed,
    policy: FailurePolicy,
) -> Result<rogue_gym_pool::Received, PoolError> {
    let mut p = pool(sabotaged(what, 3, policy));
    let id = p.id().clone();
    p.reset(None).unwrap();
    p.step(&[0; 4]).unwrap();
    let got = p.step(&[1; 4]);
    if got.is_err() {
        let e = p.step(&[1; 4]).unwrap_err().to_string();
        assert!(
            e.contains("call reset()"),
            "the next step asks for a reset: {e}"
        );
        p.reset(None).expect("a reset recovers");
    }
    p.step(&[2; 4]).expect("the pool steps after");
    p.close().unwrap();
    assert!(pool_files_gone(&id));
    got
}

/// Under the restart policy, worker 1's envs (2 and 3) report the restart and the others
/// step on; its failure is in the statistics, naming what it wrote.
fn restarted_for(what: Misdeed, words: &str) {
    let mut p = pool(sabotaged(what, 3, FailurePolicy::Restart));
    p.reset(None).unwrap();
    p.step(&[0; 4]).unwrap();
    let a = p.step(&[1; 4]).unwrap();
    assert!(a.restarted);
    let mut out = rogue_gym_pool::BatchOutput::default();
    p.read_rows(&a, None, &mut out).unwrap();
    assert_eq!(out.restarted, [false, false, true, true]);
    assert!(out.truncated[2] && out.truncated[3]);
    assert_eq!(p.restarts(), 1);
    let last = p.stats()[1].last_failure.clone().unwrap_or_default();
    assert!(
        last.contains("out of bounds") && last.contains(words),
        "{last}"
    );
    p.step(&[2; 4]).unwrap();
}

/// Under the raise policy, the call fails naming worker 1, its envs and what it wrote.
fn raised_for(what: Misdeed, words: &str) {
    let e = third_answer(what, FailurePolicy::Raise).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, PoolError::WorkerFailed(_)), "{msg}");
    assert!(
        msg.contains("worker 1") && msg.contains("envs 2..4"),
        "{msg}"
    );
    assert!(msg.contains(words), "{msg}");
}

#[test]
fn a_uniform_extra_size_beyond_the_room_is_the_workers_fault() {
    restarted_for(
        Misdeed::ExtraSize { size: 1 << 40 },
        "uniform extra-info size",
    );
    raised_for(Misdeed::ExtraSize { size: 4096 }, "outside 1..=0");
}

#[test]
fn an_info_beside_the_answer_for_a_row_outside_the_block_is_the_workers_fault() {
    restarted_for(Misdeed::ApartRow { row: 2 }, "extra info for row 2");
    raised_for(Misdeed::ApartRow { row: u32::MAX }, "hosts 2 envs");
}

#[test]
fn a_flag_byte_that_is_no_bool_is_the_workers_fault() {
    for byte in [2u8, 0x80, 255] {
        raised_for(
            Misdeed::FlagByte { byte },
            &format!("flag byte {byte} in the terminated column of env 2"),
        );
    }
    restarted_for(Misdeed::FlagByte { byte: 7 }, "flag byte 7");
}

#[test]
fn an_episode_index_at_its_limits_never_wraps_or_keeps_and_the_envs_start_over() {
    for episode in [u64::MAX, u64::MAX - 1, 1 << 62] {
        // The books are read at the next reset: it names the worker, and the envs start over.
        let mut p = pool(sabotaged(
            Misdeed::Episode { episode },
            2,
            FailurePolicy::Raise,
        ));
        p.reset(None).unwrap();
        p.step(&[0; 4]).unwrap();
        let e = p.reset(None).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("worker 1") && msg.contains(&format!("episode index {episode}")),
            "{msg}"
        );
        let a = p.reset(None).unwrap();
        let mut out = rogue_gym_pool::BatchOutput::default();
        p.read_rows(&a, None, &mut out).unwrap();
        assert_eq!(
            out.episode[2..],
            [0, 0],
            "worker 1's envs start over from episode 0"
        );
        assert!(out.episode[0] >= 1, "the others go on with their schedule");
    }
    // Under the restart policy the reset itself succeeds.
    let mut p = pool(sabotaged(
        Misdeed::Episode { episode: u64::MAX },
        2,
        FailurePolicy::Restart,
    ));
    p.reset(None).unwrap();
    p.step(&[0; 4]).unwrap();
    p.reset(None).unwrap();
    assert_eq!(p.restarts(), 1);
    p.step(&[1; 4]).unwrap();
}

#[test]
fn a_worker_killed_between_its_rows_and_its_answer_costs_one_restart() {
    restarted_for_death();
    let e = third_answer(Misdeed::DieMidWrite, FailurePolicy::Raise).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("worker 1") && msg.contains("signal 9"),
        "{msg}"
    );
}

fn restarted_for_death() {
    let mut p = pool(sabotaged(Misdeed::DieMidWrite, 3, FailurePolicy::Restart));
    p.reset(None).unwrap();
    p.step(&[0; 4]).unwrap();
    let a = p.step(&[1; 4]).unwrap();
    assert!(a.restarted);
    assert_eq!(p.restarts(), 1);
}

#[test]
fn no_process_can_resize_the_pools_buffer() {
    // Worker 1 tries through the supervisor's descriptor in /proc, as any process of the user
    // could: the seals refuse it, and the pool steps on untouched.
    let mut p = pool(sabotaged(Misdeed::Truncate, 2, FailurePolicy::Raise));
    let before = p.shared_buffer().unwrap().len();
    p.reset(None).unwrap();
    for t in 0..5 {
        p.step(&[t % 5; 4]).unwrap();
    }
    assert_eq!(p.restarts(), 0);
    assert_eq!(p.shared_buffer().unwrap().len(), before);
    let log = std::fs::read_dir(p.id().aux_dir())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with("w1."))
        .map(|e| std::fs::read_to_string(e.path()).unwrap_or_default())
        .collect::<String>();
    assert!(
        log.contains("Operation not permitted"),
        "the worker's attempt was refused: {log}"
    );
    // And this process, through its own descriptor: refused too.
    let fd = p.shared_buffer().unwrap().dup_fd().unwrap();
    let e = nix::unistd::ftruncate(&fd, 0).unwrap_err();
    assert_eq!(e, nix::errno::Errno::EPERM);
}

#[test]
fn the_async_api_checks_the_rows_it_hands_over_as_the_sync_calls_do() {
    for policy in [FailurePolicy::Raise, FailurePolicy::Restart] {
        let mut c = sabotaged(Misdeed::FlagByte { byte: 9 }, 2, policy);
        c.batch_size = Some(4);
        let mut p = pool(c);
        p.set_async_views(true);
        p.async_reset().unwrap();
        let got = p.recv().unwrap();
        p.send(&[0; 4], &got.env_ids).unwrap();
        match (policy, p.recv()) {
            (FailurePolicy::Raise, Err(e)) => {
                let msg = e.to_string();
                assert!(
                    msg.contains("worker 1") && msg.contains("flag byte 9"),
                    "{msg}"
                );
                p.async_reset().unwrap();
            }
            (FailurePolicy::Restart, Ok(got)) => {
                let mut out = rogue_gym_pool::BatchOutput::default();
                p.read_rows(&got, None, &mut out).unwrap();
                let restarted: Vec<usize> = (out.env_ids.iter().zip(&out.restarted))
                    .filter(|(_, r)| **r)
                    .map(|(&e, _)| e)
                    .collect();
                assert_eq!(restarted.len(), 2, "{:?}", got.env_ids);
                assert!(restarted.iter().all(|&e| e >= 2));
                p.send(&[1; 4], &got.env_ids).unwrap();
            }
            (policy, other) => panic!("{policy:?}: {other:?}"),
        }
        let got = p.recv().unwrap();
        assert_eq!(got.env_ids.len(), 4);
    }
}

#[test]
fn a_panic_inside_a_call_is_an_error_and_the_pool_goes_on_after_a_reset() {
    let mut p = pool(config(EXE, test_env(), 4, 2));
    p.reset(None).unwrap();
    let e = p
        .guarded(|p| -> Result<(), PoolError> {
            p.step(&[0; 4])?;
            panic!("a bug in the middle of a call")
        })
        .unwrap_err();
    assert!(matches!(e, PoolError::Internal(_)));
    assert!(
        e.to_string().contains("a bug in the middle of a call"),
        "{e}"
    );
    assert!(p.step(&[0; 4]).is_err(), "a reset comes first");
    p.reset(None).unwrap();
    p.step(&[1; 4]).unwrap();
    let id = p.id().clone();
    p.close().unwrap();
    assert!(pool_files_gone(&id));
}
