//! Unit tests of the rules on small situations.

mod smoke {
    use crate::*;

    #[test]
    fn prints() {
        for cfg in [
            GameConfig::paper(),
            GameConfig {
                hide_dungeon: false,
                ..GameConfig::default()
            },
        ] {
            let mut g = Game::new(&cfg, EpisodeConfig::default()).unwrap();
            for seed in 0..3 {
                g.reset(seed);
                println!("{}\n{}", g.screen_string(), g.status_line());
                for k in 0..200u32 {
                    g.step(
                        Action::from_index((splitmix64(k as u64 + seed * 1000) % 11) as usize)
                            .unwrap(),
                    );
                }
                println!("{}\n{}\n{:?}", g.screen_string(), g.status_line(), g.info());
            }
        }
    }
}
