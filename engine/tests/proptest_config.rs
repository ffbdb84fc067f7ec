//! Property tests: valid configs build and play; mutated invalid values are errors, never
//! panics; arbitrary JSON never panics.

use proptest::prelude::*;
use rogue_gym_engine::{Action, EpisodeConfig, Game, GameConfig, ObsBufMut, ObsSpec};

fn valid_config() -> impl Strategy<Value = String> {
    (
        32i32..=160,
        16i32..=48,
        1i32..=4,
        1i32..=3,
        0u32..=5,
        1u32..=20,
        1u32..=12,
        0u32..=6,
        prop::bool::ANY,
        prop::sample::subsequence((0usize..26).collect::<Vec<_>>(), 0..=26),
    )
        .prop_filter_map("rooms must fit their slots", |(w, h, nx, ny, empty, maze, dark, extra, hide, enemies)| {
            let json = format!(
                r#"{{"width": {w}, "height": {h}, "hide_dungeon": {hide},
                   "dungeon": {{"style": "rogue", "room_num_x": {nx}, "room_num_y": {ny},
                               "max_empty_rooms": {empty}, "maze_rate_inv": {maze}, "dark_level": {dark},
                               "max_extra_edges": {extra}}},
                   "enemies": {{"enemies": {enemies:?}}}}}"#
            );
            GameConfig::from_json(&json).ok().map(|_| json)
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn valid_configs_build_and_play(json in valid_config(), seed in 0u64..1000, actions in prop::collection::vec(0usize..11, 50..150)) {
        let cfg = GameConfig::from_json(&json).unwrap();
        let mut g = Game::new(&cfg, EpisodeConfig { max_steps: 100, stair_reward: 50.0 }).unwrap();
        g.reset(seed);
        let spec = ObsSpec::paper();
        let mut buf = vec![0u8; g.observation_shape(&spec).iter().product()];
        for a in actions {
            let r = g.step(Action::ALL[a]);
            g.write_obs(&spec, ObsBufMut::U8(&mut buf)).unwrap();
            if r.terminated || r.truncated {
                g.reset(seed + 1);
            }
        }
        prop_assert_eq!(GameConfig::from_json(&cfg.to_json()).unwrap(), cfg);
    }

    #[test]
    fn invalid_values_are_errors(
        key in prop::sample::select(vec!["width", "height", "maze_rate_inv", "dark_level", "hidden_passage_rate_inv",
                                         "locked_door_rate_inv", "door_unlock_rate_inv", "passage_unlock_rate_inv",
                                         "room_num_x", "room_num_y", "hunger_time", "init_hp"]),
        bad in prop::sample::select(vec![-5i64, 0, 1, 2, 7, 15, 31, 161, 1000, -1]),
    ) {
        let json = match key {
            "width" | "height" => format!(r#"{{"{key}": {bad}}}"#),
            "hunger_time" | "init_hp" => format!(r#"{{"player": {{"{key}": {bad}}}}}"#),
            _ => format!(r#"{{"dungeon": {{"style": "rogue", "{key}": {bad}}}}}"#),
        };
        // Either accepted (a valid value) and then playable, or rejected naming the key.
        match GameConfig::from_json(&json) {
            Ok(cfg) => {
                let mut g = Game::new(&cfg, EpisodeConfig::default()).unwrap();
                g.step(Action::Right);
            }
            Err(e) => {
                let msg = e.to_string();
                prop_assert!(msg.contains(key) || msg.contains("min_room_size"), "{}: {}", json, msg);
            }
        }
    }

    #[test]
    fn arbitrary_json_never_panics(s in "\\PC{0,60}") {
        let _ = GameConfig::from_json(&s);
    }
}

/// Extreme integers in every integer key (top level, dungeon, gold, player, starting items,
/// custom monsters): an error naming the key or a playable game, never a panic (debug builds
/// check overflow, so an unchecked `abs` or product would panic here).
#[test]
fn extreme_integers_are_errors_or_games_never_panics() {
    let extremes = [
        i64::from(i32::MIN),
        i64::from(i32::MIN) + 1,
        -1,
        i64::from(i32::MAX),
        i64::from(u32::MAX),
        i64::MAX,
    ];
    // (what the error must name, the config with V for the value)
    let templates: &[(&str, &str)] = &[
        ("width", r#"{"width": V}"#),
        ("height", r#"{"height": V}"#),
        (
            "room_num_x",
            r#"{"dungeon": {"style": "rogue", "room_num_x": V, "room_num_y": V}}"#,
        ),
        (
            "max_empty_rooms",
            r#"{"dungeon": {"style": "rogue", "max_empty_rooms": V}}"#,
        ),
        (
            "max_extra_edges",
            r#"{"dungeon": {"style": "rogue", "max_extra_edges": V}}"#,
        ),
        (
            "amulet_level",
            r#"{"dungeon": {"style": "rogue", "amulet_level": V}}"#,
        ),
        (
            "gold",
            r#"{"item": {"gold": {"base": V, "per_level": V, "minimum": V, "rate_inv": 2}}}"#,
        ),
        ("init_hp", r#"{"player": {"init_hp": V}}"#),
        ("init_str", r#"{"player": {"init_str": V}}"#),
        ("hunger_time", r#"{"player": {"hunger_time": V}}"#),
        (
            "def_plus",
            r#"{"player": {"init_items": [{"Armor": {"name": "ring mail", "def_plus": V}}]}}"#,
        ),
        (
            "item.armor.armors[0]",
            r#"{"item": {"armor": {"armors": [{"name": "ring mail", "def": V}]}}}"#,
        ),
        (
            "hit_plus",
            r#"{"player": {"init_items": [{"Weapon": {"name": "mace", "hit_plus": V, "dam_plus": 1}}]}}"#,
        ),
        (
            "dam_plus",
            r#"{"player": {"init_items": [{"Weapon": {"name": "mace", "hit_plus": 1, "dam_plus": V}}]}}"#,
        ),
        (
            "enemies.enemies[0]",
            r#"{"enemies": {"enemies": [{"attack": [], "attr": 0, "defense": V, "exp": 1,
            "gold": 0, "level": 1, "name": "x", "tile": 88, "rarelity": 1}]}}"#,
        ),
        (
            "enemies.enemies[0]",
            r#"{"enemies": {"enemies": [{"attack": [], "attr": 0, "defense": 3, "exp": 1,
            "gold": 0, "level": V, "name": "x", "tile": 88, "rarelity": 1}]}}"#,
        ),
    ];
    for (key, template) in templates {
        for v in extremes {
            let json = template.replace('V', &v.to_string());
            match GameConfig::from_json(&json) {
                Ok(cfg) => {
                    let mut g = Game::new(&cfg, EpisodeConfig::default()).unwrap();
                    for a in Action::ALL {
                        g.step(a);
                    }
                }
                Err(e) => {
                    let msg = e.to_string();
                    assert!(
                        msg.contains(key)
                            || msg.contains("min_room_size")
                            || msg.contains("item.gold"),
                        "{json}: the error does not name {key}: {msg}"
                    );
                }
            }
        }
    }
}
