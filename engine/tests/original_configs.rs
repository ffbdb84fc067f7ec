//! The original's own config files (`../shared/reference/original-configs/`, read in place,
//! never copied) load unchanged, play, and read back from what we write.

use std::path::PathBuf;

use rogue_gym_engine::config::{InitItem, ItemKind};
use rogue_gym_engine::{Action, EpisodeConfig, Game, GameConfig};

/// The folder of the original's configs, or `None` (skip) outside CI when `../shared` is absent.
fn original_configs() -> Option<PathBuf> {
    let dir =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/reference/original-configs");
    if dir.is_dir() {
        return Some(dir);
    }
    assert!(
        std::env::var("CI").as_deref() != Ok("true"),
        "CI must run with ../shared beside the repository: {} is missing",
        dir.display()
    );
    eprintln!("skipped: {} is missing", dir.display());
    None
}

#[test]
fn the_originals_config_files_load_play_and_round_trip() {
    let Some(dir) = original_configs() else {
        return;
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    files.sort();
    assert!(
        files.len() >= 5,
        "expected the original's 5 configs in {}",
        dir.display()
    );
    for path in files {
        let text = std::fs::read_to_string(&path).unwrap();
        let cfg = GameConfig::from_json(&text)
            .unwrap_or_else(|e| panic!("{} does not load: {e}", path.display()));
        let mut game = Game::new(&cfg, EpisodeConfig::default()).unwrap();
        game.reset(3);
        for t in 0..300 {
            if game.step(Action::ALL[t % Action::ALL.len()]).terminated {
                game.reset(t as u64);
            }
        }
        assert_eq!(
            GameConfig::from_json(&cfg.to_json()).unwrap(),
            cfg,
            "{}",
            path.display()
        );
    }
}

#[test]
fn the_defaults_food_is_the_originals_ration_and_a_trailing_zero_exp_is_accepted() {
    let Some(dir) = original_configs() else {
        return;
    };
    let text = std::fs::read_to_string(dir.join("config-default.json")).unwrap();
    let cfg = GameConfig::from_json(&text).unwrap();
    assert_eq!(cfg.player.exps.last(), Some(&0));
    let food = cfg.player.init_items.iter().find_map(|i| match i {
        InitItem::Noinit(n) if n.kind.name() == "Food" => Some(n.kind.clone()),
        _ => None,
    });
    let Some(ItemKind::WithSub(m)) = food else {
        panic!("no food item: {food:?}")
    };
    assert_eq!(m.get("Food").map(String::as_str), Some("Ration"));
    // Our defaults say the same as the original's file.
    assert_eq!(
        cfg.player.init_items,
        GameConfig::default().player.init_items
    );
}

#[test]
fn a_sub_kind_map_must_have_one_entry() {
    let json = r#"{"player": {"init_items": [{"Noinit": {"kind": {"Food": "Ration", "Potion": "x"}, "how_many": 1}}]}}"#;
    let e = GameConfig::from_json(json).unwrap_err().to_string();
    assert!(e.contains("player.init_items[0].kind"), "{e}");
    let json = r#"{"player": {"exps": [10, 5, 0]}}"#;
    let e = GameConfig::from_json(json).unwrap_err().to_string();
    assert!(e.contains("player.exps"), "{e}");
}
