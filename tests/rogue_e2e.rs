//! End-to-end tests of the pool hosting the Rogue-Gym game (the `"rogue"` env kind).

use rogue_gym_e2e::Copying;
use rogue_gym_e2e::*;
use rogue_gym_pool::{BatchOutput, EnvRegistry, Pool, SeedPolicy, SeedSet};
use serde_json::json;

const EXE: &str = env!("CARGO_BIN_EXE_e2e_worker");

fn rogue() -> serde_json::Value {
    // Short episodes so that autoresets happen within the test.
    json!({"kind": "rogue", "config": null, "max_steps": 25})
}

#[test]
fn rogue_trajectories_identical_for_1_2_4_8_workers_and_sync_async() {
    let reg = EnvRegistry::with_defaults();
    let steps = 60;
    let mut reference = None;
    for workers in [1, 2, 4, 8] {
        let mut p = Pool::new(config(EXE, rogue(), 8, workers), &reg).unwrap();
        assert_eq!(p.spec().obs_shape, vec![17, 16, 32]);
        let d = run_sync(&mut p, steps).unwrap();
        match &reference {
            None => reference = Some(d),
            Some(r) => assert_eq!(&d, r, "sync with {workers} workers differs"),
        }
    }
    let reference = reference.unwrap();
    let mut p = Pool::new(config(EXE, rogue(), 8, 2), &reg).unwrap();
    assert_eq!(run_sync_shared(&mut p, steps).unwrap(), reference);
    for (workers, batch) in [(4, 4), (8, 2)] {
        let mut c = config(EXE, rogue(), 8, workers);
        c.batch_size = Some(batch);
        let mut p = Pool::new(c, &reg).unwrap();
        assert_eq!(
            run_async(&mut p, steps).unwrap(),
            reference,
            "async with {workers} workers, batch {batch} differs"
        );
    }
}

#[test]
fn rogue_pool_matches_a_bare_game() {
    // Env 3 of a pool plays exactly the episode a bare engine plays from the same seed.
    let reg = EnvRegistry::with_defaults();
    let mut c = config(EXE, rogue(), 4, 2);
    c.seeds.set = Some(SeedSet::List(vec![1000, 1001, 1002, 1003]));
    c.seeds.policy = SeedPolicy::Sequential;
    let mut p = Pool::new(c, &reg).unwrap();
    let ob = p.obs_bytes();
    let mut obs = vec![0u8; 4 * ob];
    let mut out = BatchOutput::default();
    p.reset_into(&mut obs, &mut out).unwrap();
    assert_eq!(out.seed[3], 1003);
    let mut bare = reg.make(&rogue(), 0).unwrap();
    let mut bobs = vec![0u8; ob];
    bare.reset(1003, &mut bobs).unwrap();
    assert_eq!(&obs[3 * ob..], &bobs[..]);
    let mut ret = 0.0;
    for t in 0..20u64 {
        let actions: Vec<i64> = (0..4).map(|i| action(i, t, 11)).collect();
        p.step_into(&actions, &mut obs, &mut out).unwrap();
        let o = bare.step(actions[3] as usize, &mut bobs).unwrap();
        ret += o.reward;
        assert_eq!(&obs[3 * ob..], &bobs[..], "step {t}");
        assert_eq!(out.reward[3], o.reward);
        assert_eq!(out.episode_return[3], ret);
        let mut info = [0.0; 8];
        bare.info(&mut info);
        assert_eq!(&out.info[3 * 8..4 * 8], &info[..], "floor/gold/hp/... info");
    }
}
