//! Same config + seed + actions => identical game; different seeds differ.

use rogue_gym_engine::{
    Action, ENGINE_VERSION, EpisodeConfig, Game, GameConfig, ObsBufMut, ObsSpec, StatusFlags,
    splitmix64,
};

/// FNV-1a over every observation (one-hot + status + history) and reward of a long random
/// episode sequence.
fn digest(cfg: &GameConfig, seed: u64, steps: u32) -> u64 {
    let mut g = Game::new(
        cfg,
        EpisodeConfig {
            max_steps: 300,
            stair_reward: 50.0,
        },
    )
    .unwrap();
    g.reset(seed);
    let spec = ObsSpec {
        status: StatusFlags::FULL,
        history: true,
        ..ObsSpec::paper()
    };
    let mut buf = vec![0u8; g.observation_shape(&spec).iter().product()];
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |b: u8| {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x100_0000_01b3);
    };
    let mut state = seed;
    let mut episode = 0;
    for _ in 0..steps {
        state = splitmix64(state);
        let r = g.step(Action::ALL[(state % 11) as usize]);
        g.write_obs(&spec, ObsBufMut::U8(&mut buf)).unwrap();
        // Fold the observation 8 bytes at a time, then feed the result to the byte hash.
        let mut fold = 0u64;
        for chunk in buf.chunks(8) {
            let mut w = [0u8; 8];
            w[..chunk.len()].copy_from_slice(chunk);
            fold = (fold ^ u64::from_le_bytes(w))
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .rotate_left(29);
        }
        fold.to_le_bytes().iter().for_each(|&b| eat(b));
        r.reward
            .to_bits()
            .to_le_bytes()
            .iter()
            .for_each(|&b| eat(b));
        eat(u8::from(r.terminated) + 2 * u8::from(r.truncated));
        if r.terminated || r.truncated {
            episode += 1;
            g.reset(seed.wrapping_add(episode * 1000));
        }
    }
    h
}

/// The digest of the games [`ENGINE_VERSION`] plays: the paper's config and the default one,
/// a few seeds, every observation and reward of 2,000 random steps each.
const GAMES_OF_VERSION: (u32, u64) = (1, 896_879_069_792_266_738);

#[test]
fn the_engine_version_names_the_games_it_plays() {
    let mut h = 0u64;
    for cfg in [GameConfig::paper(), GameConfig::default()] {
        for seed in [0, 1, 12345] {
            h = splitmix64(h ^ digest(&cfg, seed, 2000));
        }
    }
    assert_eq!(
        (ENGINE_VERSION, h),
        GAMES_OF_VERSION,
        "the games changed (a dungeon or a rule): raise ENGINE_VERSION (engine/src/lib.rs), \
         record the new digest here and say in the CHANGELOG what changed"
    );
}

#[test]
fn digests_are_reproducible() {
    for cfg in [GameConfig::paper(), GameConfig::default()] {
        for seed in [0, 1, 12345] {
            let a = digest(&cfg, seed, 2000);
            let b = digest(&cfg, seed, 2000);
            assert_eq!(a, b, "seed {seed}");
        }
        assert_ne!(digest(&cfg, 1, 500), digest(&cfg, 2, 500));
    }
}

#[test]
fn reset_reproduces_the_first_floor() {
    let mut g = Game::new(&GameConfig::default(), EpisodeConfig::default()).unwrap();
    g.reset(77);
    let first = g.screen_string();
    for i in 0..200 {
        g.step(Action::ALL[i % 11]);
    }
    g.reset(3);
    g.reset(77);
    assert_eq!(g.screen_string(), first);
    let other = Game::new(
        &GameConfig {
            seed: Some(77),
            ..GameConfig::default()
        },
        EpisodeConfig::default(),
    )
    .unwrap();
    assert_eq!(other.screen_string(), first);
}

/// Floor 2's layout does not depend on what happened on floor 1.
#[test]
fn floor_layout_is_independent_of_play() {
    let cfg = GameConfig {
        hide_dungeon: false,
        ..GameConfig::paper()
    };
    let floor2 = |extra_searches: usize| {
        let mut g = Game::new(
            &cfg,
            EpisodeConfig {
                max_steps: 100_000,
                stair_reward: 50.0,
            },
        )
        .unwrap();
        g.reset(5);
        for _ in 0..extra_searches {
            g.step(Action::Search);
        }
        // Walk to the stairs by trying every action until the floor changes (random walk).
        let mut state = 9u64;
        while g.info().floor == 1 {
            state = splitmix64(state);
            g.step(Action::ALL[(state % 11) as usize]);
        }
        // Mask the player and compare the remaining layout.
        g.screen_string().replace('@', ".")
    };
    let a = floor2(0);
    let b = floor2(7);
    let diff = a.bytes().zip(b.bytes()).filter(|(x, y)| x != y).count();
    assert!(diff <= 2, "only the player's start may differ:\n{a}\n{b}");
}
