//! Random play with all monsters on the default 80x24 dungeon: no panics, invariants hold.

use rogue_gym_engine::{
    Action, Dtype, Encoding, EpisodeConfig, Game, GameConfig, ObsBufMut, ObsSpec, StatusFlags,
    splitmix64,
};

fn play(episodes: u64, first: u64) -> (u64, u64) {
    let cfg = GameConfig::default();
    let mut g = Game::new(
        &cfg,
        EpisodeConfig {
            max_steps: 100,
            stair_reward: 50.0,
        },
    )
    .unwrap();
    let onehot = ObsSpec {
        status: StatusFlags::FULL,
        history: true,
        ..ObsSpec::paper()
    };
    let gray = ObsSpec {
        encoding: Encoding::Gray,
        dtype: Dtype::F32,
        normalize_status: true,
        status: StatusFlags::FULL,
        history: true,
    };
    let mut buf = vec![0u8; g.observation_shape(&onehot).iter().product()];
    let mut fbuf = vec![0f32; g.observation_shape(&gray).iter().product()];
    let (mut deaths, mut steps) = (0, 0);
    let mut state = first;
    for e in first..first + episodes {
        g.reset(e);
        loop {
            state = splitmix64(state);
            // Bias towards moves so the player meets monsters and stairs.
            let a = Action::ALL[(state % 11) as usize];
            let r = g.step(a);
            steps += 1;
            let s = g.status();
            assert!(
                s.hp_current <= s.hp_max,
                "hp {} > max {}",
                s.hp_current,
                s.hp_max
            );
            assert!(s.hp_current >= 0);
            let (x, y) = g.player_position();
            assert!(y >= 1 && (y as usize) < g.height() - 1 && (x as usize) < g.width());
            let row = g.screen_rows().nth(y as usize).unwrap();
            assert_eq!(row[x as usize], b'@');
            if steps % 8 == 0 {
                g.write_obs(&onehot, ObsBufMut::U8(&mut buf)).unwrap();
                g.write_obs(&gray, ObsBufMut::F32(&mut fbuf)).unwrap();
                assert!(fbuf.iter().all(|v| (0.0..=1.0).contains(v)));
            }
            if r.terminated || r.truncated {
                deaths += u64::from(g.info().died);
                assert!(r.terminated == (g.info().died || g.info().won));
                break;
            }
        }
    }
    (deaths, steps)
}

#[test]
fn random_play_10k_episodes_part1() {
    let (deaths, steps) = play(5_000, 0);
    eprintln!("deaths {deaths} / 5000, steps {steps}");
}

#[test]
fn random_play_10k_episodes_part2() {
    let (deaths, steps) = play(5_000, 1_000_000);
    eprintln!("deaths {deaths} / 5000, steps {steps}");
}
