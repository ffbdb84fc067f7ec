//! End-to-end tests of workers replaced by plan (`recycle_after_steps`): the envs of a
//! replaced worker start their next episodes, and their first rows are those episodes' own,
//! whichever API answers them.

use rogue_gym_e2e::*;

const EXE: &str = env!("CARGO_BIN_EXE_e2e_worker");

#[test]
fn async_answers_of_a_recycled_worker_are_its_envs_next_episodes_first_rows() {
    // A sync reset and steps, then send/recv (TorchRL's loop starts so). Workers replaced by
    // plan (the first time at the first send) reset their envs into the slots the async API
    // chose; every restarted row must be exactly the first observation of the episode its
    // record names, whether handed over as a view or copied.
    use rogue_gym_pool::{Env, TestEnv};
    for views in [false, true] {
        let mut c = config(EXE, test_env(), 8, 2);
        c.batch_size = Some(4);
        c.recycle_after_steps = Some(12);
        let mut p = pool(c);
        p.set_async_views(views);
        let ob = p.obs_bytes();
        p.reset(None).unwrap();
        for _ in 0..3 {
            p.step(&[2i64; 8]).unwrap();
        }
        let all: Vec<usize> = (0..8).collect();
        p.send(&[1i64; 8], &all).unwrap();
        let mut fresh = TestEnv::from_json(&test_env()).unwrap();
        let mut want = vec![0u8; ob];
        let mut restarts = 0;
        for t in 0..80 {
            let got = p.recv().unwrap();
            // A view or gathered rows, copied out alike.
            let (mut out, mut obs) = (rogue_gym_pool::BatchOutput::default(), vec![0; 4 * ob]);
            p.read_rows(&got, Some(&mut obs), &mut out).unwrap();
            assert_eq!(out.env_ids, got.env_ids);
            for (r, &e) in out.env_ids.iter().enumerate() {
                if out.restarted[r] {
                    restarts += 1;
                    fresh.reset(out.seed[r], &mut want).unwrap();
                    let row = &obs[r * ob..(r + 1) * ob];
                    assert_eq!(row, want, "env {e}'s restart (views: {views})");
                }
            }
            let ids = got.env_ids.clone();
            p.send(&vec![(t % 5) as i64; ids.len()], &ids).unwrap();
        }
        assert!(
            restarts >= 8,
            "every env was recycled at least once ({restarts})"
        );
        assert!(!p.recycled_envs().is_empty() || restarts > 0);
    }
}
