//! Config parsing, round trip and error messages.

use rogue_gym_engine::config::{Chase, EnemiesConfig, Seeding};
use rogue_gym_engine::{ConfigError, EpisodeConfig, Game, GameConfig};

fn err(json: &str) -> String {
    match GameConfig::from_json(json) {
        Ok(_) => panic!("{json} should be rejected"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn empty_is_default() {
    assert_eq!(GameConfig::from_json("{}").unwrap(), GameConfig::default());
    let d = GameConfig::default();
    assert_eq!((d.width, d.height, d.hide_dungeon), (80, 24, true));
    assert_eq!(d.symbol_count(), 43);
}

#[test]
fn round_trip() {
    let original_seeding = GameConfig {
        seeding: Seeding::Original,
        enemies: EnemiesConfig {
            chase: Chase::Original,
            spawn_on_objects: true,
            ..Default::default()
        },
        ..GameConfig::paper()
    };
    for cfg in [GameConfig::default(), GameConfig::paper(), original_seeding] {
        let json = cfg.to_json();
        assert_eq!(GameConfig::from_json(&json).unwrap(), cfg, "{json}");
        // The original rejects `"keymap": null`: an unset keymap is left out.
        assert!(!json.contains("keymap"), "{json}");
    }
    let json =
        GameConfig::from_json(r#"{"seeding": "original", "enemies": {"chase": "original"}}"#)
            .unwrap()
            .to_json();
    assert!(json.contains(r#""seeding":"original""#) && json.contains(r#""chase":"original""#));
    assert!(
        GameConfig::from_json(r#"{"seeding": "raw"}"#)
            .unwrap_err()
            .to_string()
            .contains("seeding")
    );
}

#[test]
fn paper_config_loads() {
    let json = r#"{"width": 32, "height": 16, "seed_range": [0, 40], "hide_dungeon": true,
 "dungeon": {"style": "rogue", "room_num_x": 2, "room_num_y": 2,
             "min_room_size": {"x": 4, "y": 4}, "max_empty_rooms": 3, "amulet_level": 25,
             "maze_rate_inv": 15, "dark_level": 10, "hidden_passage_rate_inv": 40,
             "locked_door_rate_inv": 5, "max_extra_edges": 5,
             "door_unlock_rate_inv": 5, "passage_unlock_rate_inv": 3, "enable_trap": true},
 "enemies": {"enemies": []}}"#;
    let cfg = GameConfig::from_json(json).unwrap();
    assert_eq!(cfg, GameConfig::paper());
    assert_eq!(cfg.symbol_count(), 17);
    let g = Game::new(&cfg, EpisodeConfig::default()).unwrap();
    assert_eq!((g.height(), g.width()), (16, 32));
}

#[test]
fn original_items_keymap_and_custom_enemy_parse() {
    let json = r#"{
      "seed": 1,
      "item": {"gold": {"rate_inv": 3, "base": 40, "per_level": 5, "minimum": 1},
               "armor": {"armors": [0, 7], "cursed_rate": 10, "powerup_rate": 5},
               "weapon": {"weapons": [0, 1], "cursed_rate": 10, "powerup_rate": 5}},
      "player": {"init_items": [{"Noinit": {"kind": "Gold", "how_many": 7, "attr": 4}},
                                {"Armor": {"name": "plate mail", "def_plus": 2}},
                                {"Weapon": {"name": "long sword", "num_plus": 0, "hit_plus": 0, "dam_plus": 0}}]},
      "keymap": {"h": {"Act": {"Move": "Left"}}, "Q": {"Sys": "Quit"}, "y": {"Both": {"act": {"Move": "LeftUp"}, "sys": "Yes"}}},
      "enemies": {"enemies": [1, {"attack": [{"times": 1, "max": 2}], "attr": 1, "defense": 3, "exp": 1,
                                 "gold": 0, "level": 1, "name": "ghoul", "tile": 71, "rarelity": 3}]}
    }"#;
    let cfg = GameConfig::from_json(json).unwrap();
    assert_eq!(cfg.symbol_count(), 17 + 7, "G is the highest letter");
    let g = Game::new(&cfg, EpisodeConfig::default()).unwrap();
    assert_eq!(g.status().gold, 7);
    assert_eq!(g.status().defense, 9);
}

#[test]
fn starting_items_come_from_the_configured_tables() {
    // A custom armour in the table is what the player starts wearing.
    let json = r#"{"item": {"armor": {"armors": [{"name": "mithril coat", "def": 9}]},
                            "weapon": {"weapons": [{"name": "club", "dice": {"times": 1, "max": 3}}]}},
                   "player": {"init_items": [{"Armor": {"name": "Mithril Coat", "def_plus": 1}},
                                             {"Weapon": {"name": "club", "hit_plus": 0, "dam_plus": 0}}]}}"#;
    let cfg = GameConfig::from_json(json).unwrap();
    assert_eq!(cfg.item.armor.defense_of("mithril-coat"), Some(9));
    assert_eq!(cfg.item.weapon.dice_of("club"), Some((1, 3)));
    let g = Game::new(&cfg, EpisodeConfig::default()).unwrap();
    assert_eq!(g.status().defense, 10);
    // A builtin entry is found by its builtin name; `bow` stands for `short bow`.
    let d = GameConfig::default();
    assert_eq!(d.item.armor.defense_of("ring mail"), Some(3));
    assert_eq!(d.item.weapon.dice_of("bow"), Some((1, 1)));
    // A starting item missing from the configured table is an error naming the item.
    let e = err(r#"{"item": {"armor": {"armors": [0]}},
                    "player": {"init_items": [{"Armor": {"name": "ring mail", "def_plus": 1}}]}}"#);
    assert!(
        e.contains("player.init_items[0].name") && e.contains("item.armor.armors"),
        "{e}"
    );
    let e = err(r#"{"item": {"weapon": {"weapons": [0]}},
                    "player": {"init_items": [{"Weapon": {"name": "dagger"}}]}}"#);
    assert!(
        e.contains("player.init_items[0].name") && e.contains("item.weapon.weapons"),
        "{e}"
    );
    // The default inventory (ring mail, mace, bow, arrows) needs those entries in the tables.
    let e = err(r#"{"item": {"weapon": {"weapons": [0, 2]}}}"#);
    assert!(
        e.contains("init_items[5].name") && e.contains("arrow"),
        "{e}"
    );
    // A custom armour's defence is bounded (10 - defence must not overflow).
    let e = err(r#"{"item": {"armor": {"armors": [{"name": "x", "def": -2147483648}]}}}"#);
    assert!(e.contains("item.armor.armors[0].def"), "{e}");
}

#[test]
fn unknown_keys_are_named_at_every_level() {
    assert!(err(r#"{"widht": 80}"#).contains("unknown key `widht`"));
    let e = err(r#"{"dungeon": {"style": "rogue", "room_numx": 2}}"#);
    assert!(e.contains("`room_numx`") && e.contains("dungeon"), "{e}");
    assert!(
        err(r#"{"dungeon": {"style": "rogue", "min_room_size": {"x": 4, "z": 1}}}"#)
            .contains("`z`")
    );
    assert!(err(r#"{"player": {"hp": 3}}"#).contains("`hp`"));
    assert!(err(r#"{"enemies": {"enemy": []}}"#).contains("`enemy`"));
    assert!(err(r#"{"item": {"gold": {"rate": 2}}}"#).contains("`rate`"));
}

#[test]
fn invalid_values_say_what_and_why() {
    let e = err(r#"{"width": 31}"#);
    assert!(e.contains("`width` = 31") && e.contains("32..=160"), "{e}");
    assert!(err(r#"{"height": 49}"#).contains("`height` = 49"));
    let e = err(r#"{"dungeon": {"style": "rogue", "maze_rate_inv": 0}}"#);
    assert!(
        e.contains("`dungeon.maze_rate_inv`") && e.contains(">= 1"),
        "{e}"
    );
    for key in [
        "dark_level",
        "hidden_passage_rate_inv",
        "locked_door_rate_inv",
        "door_unlock_rate_inv",
        "passage_unlock_rate_inv",
    ] {
        assert!(
            err(&format!(
                r#"{{"dungeon": {{"style": "rogue", "{key}": 0}}}}"#
            ))
            .contains(key)
        );
    }
    let e = err(
        r#"{"width": 32, "height": 16, "dungeon": {"style": "rogue", "room_num_x": 4, "room_num_y": 3}}"#,
    );
    assert!(
        e.contains("min_room_size") && e.contains("too small"),
        "{e}"
    );
    assert!(err(r#"{"dungeon": {"style": "nethack"}}"#).contains("not supported"));
    assert!(
        err(r#"{"dungeon": {"room_num_x": 2}}"#).contains("style"),
        "style is required"
    );
    assert!(err(r#"{"seed_range": [5, 5]}"#).contains("seed_range"));
    assert!(err(r#"{"enemies": {"enemies": [26]}}"#).contains("enemies.enemies[0]"));
    assert!(err(r#"{"keymap": {"FO": {"Act": "Search"}}}"#).contains("keymap"));
    assert!(err(r#"{"width": "wide"}"#).contains("width"));
    assert!(err("not json").contains("invalid config"));
    assert!(matches!(
        GameConfig::from_json(r#"{"width": 31}"#),
        Err(ConfigError::Invalid { .. })
    ));
}

#[test]
fn zero_extra_edges_is_a_valid_config() {
    // That it means no extra edge (a spanning tree of the rooms, nothing more) is asserted
    // where the edges are chosen (`dungeon/passages.rs`).
    let cfg =
        GameConfig::from_json(r#"{"dungeon": {"style": "rogue", "max_extra_edges": 0}}"#).unwrap();
    assert_eq!(cfg.dungeon.max_extra_edges, 0);
    let mut g = Game::new(&cfg, EpisodeConfig::default()).unwrap();
    for s in 0..50 {
        g.reset(s);
    }
}

#[test]
fn episode_config_serde() {
    let e: EpisodeConfig = serde_json::from_str(r#"{"max_steps": 500}"#).unwrap();
    assert_eq!(
        e,
        EpisodeConfig {
            max_steps: 500,
            stair_reward: 50.0
        }
    );
    assert!(serde_json::from_str::<EpisodeConfig>(r#"{"max_step": 500}"#).is_err());
}

#[test]
fn seeds() {
    let cfg = GameConfig::paper();
    assert!((0..100).all(|e| cfg.seed_for_episode(e) < 40));
    let fixed = GameConfig {
        seed: Some(9),
        ..GameConfig::paper()
    };
    assert_eq!(fixed.seed_for_episode(3), 9);
    assert_eq!(
        Game::new(&fixed, EpisodeConfig::default())
            .unwrap()
            .info()
            .seed,
        9
    );
}

#[test]
fn tiny_rooms_still_have_stairs() {
    let cfg = GameConfig::from_json(
        r#"{"width": 32, "height": 16, "enemies": {"enemies": []},
            "dungeon": {"style": "rogue", "room_num_x": 1, "room_num_y": 1, "min_room_size": {"x": 3, "y": 3}},
            "item": {"gold": {"rate_inv": 1}}}"#,
    )
    .unwrap();
    let mut g = Game::new(&cfg, EpisodeConfig::default()).unwrap();
    for seed in 0..300 {
        g.reset(seed);
        let s = GameConfig {
            hide_dungeon: false,
            ..cfg.clone()
        };
        let mut open = Game::new(&s, EpisodeConfig::default()).unwrap();
        open.reset(seed);
        let screen = open.screen_string();
        assert!(
            screen.contains('%') || screen.contains('*') || screen.contains('@'),
            "{screen}"
        );
    }
}
