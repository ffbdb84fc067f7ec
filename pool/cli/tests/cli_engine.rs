//! Tests of the engine-facing `rogue-gym` subcommands: play/bench/replay config errors,
//! replay reproducing a recorded game, and bench with few steps.

use std::path::PathBuf;
use std::process::{Command, Output};

use rogue_gym_engine::{Action, EpisodeConfig, Game, GameConfig};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_rogue-gym"))
}

/// A test's own scratch directory, removed when the test ends (passed or failed).
struct Scratch(PathBuf);

impl Scratch {
    fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("rogue-gym-cli-{}-{test}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }
    fn file(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn bad_config_is_reported_with_the_key() {
    let scratch = Scratch::new("bad_config");
    let path = scratch.file("bad.json");
    std::fs::write(&path, r#"{"widht": 80}"#).unwrap();
    for sub in ["play", "bench"] {
        let o = bin().args([sub, "--config"]).arg(&path).output().unwrap();
        let (_, err) = text(&o);
        assert!(!o.status.success(), "{sub}");
        assert!(err.contains("`widht`"), "{sub}: {err}");
        assert!(
            !err.contains("panicked") && !err.contains("backtrace"),
            "{err}"
        );
    }
    std::fs::write(
        &path,
        r#"{"dungeon": {"style": "rogue", "maze_rate_inv": 0}}"#,
    )
    .unwrap();
    let o = bin()
        .args(["bench", "--steps", "10", "--config"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(text(&o).1.contains("dungeon.maze_rate_inv"));
    let o = bin()
        .args(["bench", "--config", "/nonexistent/x.json"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(text(&o).1.contains("cannot read config"));
}

#[test]
fn bench_runs() {
    let o = bin().args(["bench", "--steps", "2000"]).output().unwrap();
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        out.contains("steps/s") && out.contains("[17, 16, 32]"),
        "{out}"
    );
    let o = bin()
        .args([
            "bench",
            "--steps",
            "500",
            "--encoding",
            "gray",
            "--dtype",
            "f32",
        ])
        .output()
        .unwrap();
    assert!(o.status.success());
    let o = bin().args(["bench", "--encoding", "rgb"]).output().unwrap();
    assert!(!o.status.success());
}

#[test]
fn replay_reproduces_the_final_state() {
    let cfg = GameConfig::paper();
    let keys = "llllljjjjjhhhhkkkk>s.ynbuLJHK".repeat(8);
    // The reference game, played through the library.
    let mut game = Game::new(
        &cfg,
        EpisodeConfig {
            max_steps: 400,
            stair_reward: 50.0,
        },
    )
    .unwrap();
    game.reset(11);
    for c in keys.chars() {
        game.step_command(rogue_gym_engine::Command::from_key(c).unwrap());
    }
    let log = serde_json::json!({
        "config": serde_json::from_str::<serde_json::Value>(&cfg.to_json()).unwrap(),
        "seed": 11,
        "max_steps": 400,
        "actions": keys.chars().map(|c| c.to_string()).collect::<Vec<_>>(),
    });
    let scratch = Scratch::new("replay");
    let path = scratch.file("log.json");
    std::fs::write(&path, log.to_string()).unwrap();
    let o = bin()
        .arg("replay")
        .arg(&path)
        .arg("--no-tty")
        .output()
        .unwrap();
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let screen: Vec<String> = game
        .screen_rows()
        .skip(1)
        .take(game.height() - 2)
        .map(|r| String::from_utf8_lossy(r).into_owned())
        .collect();
    for row in &screen {
        assert!(out.contains(row.as_str()), "row {row:?} missing in\n{out}");
    }
    assert!(out.contains(&game.status_line()));
    assert!(
        out.contains(&format!("steps {}", game.info().steps)),
        "{out}"
    );
    let _ = Action::NoOp;
}

#[test]
fn replay_rejects_bad_logs() {
    let scratch = Scratch::new("bad_logs");
    let path = scratch.file("badlog.json");
    std::fs::write(
        &path,
        r#"{"config": {"widht": 3}, "seed": 1, "actions": []}"#,
    )
    .unwrap();
    let o = bin()
        .arg("replay")
        .arg(&path)
        .arg("--no-tty")
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(text(&o).1.contains("widht"));
    std::fs::write(&path, r#"{"config": {}, "seed": 1, "actions": ["x"]}"#).unwrap();
    let o = bin()
        .arg("replay")
        .arg(&path)
        .arg("--no-tty")
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(text(&o).1.contains("unknown key"));
}

#[test]
fn dump_writes_one_record_per_seed_and_floor_in_the_oracles_format() {
    let o = bin()
        .args(["dump", "--seed", "1000..1003", "--floors", "3"])
        .output()
        .unwrap();
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let records: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(records.len(), 9);
    for (k, r) in records.iter().enumerate() {
        assert_eq!(r["seed"], 1000 + k as u64 / 3);
        assert_eq!(r["floor"], 1 + k as u64 % 3);
        assert_eq!(
            r["reached_by"],
            if k % 3 == 0 { "start" } else { "teleport" }
        );
        let map: Vec<&str> = r["map"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s.as_str().unwrap())
            .collect();
        assert_eq!(map.len(), 16);
        assert!(map.iter().all(|row| row.len() == 32));
        let at = |p: &serde_json::Value| {
            map[p[1].as_u64().unwrap() as usize].as_bytes()[p[0].as_u64().unwrap() as usize]
        };
        assert_eq!(at(&r["stairs"]), b'%');
        assert!(matches!(at(&r["player_start"]), b'.' | b'#'), "{r}");
        assert_ne!(r["player_start"], r["stairs"]);
        let locked = r["locked_doors"].as_array().unwrap();
        for d in r["doors"].as_array().unwrap() {
            let want: &[u8] = if locked.contains(d) { b"-|" } else { b"+" };
            assert!(want.contains(&at(d)), "door {d} in {r}");
        }
        for h in r["hidden_passages"].as_array().unwrap() {
            assert!(matches!(at(h), b' ' | b'#'), "hidden passage {h}");
        }
        assert_eq!(r["rooms"].as_array().unwrap().len(), 4);
    }
    // The same fields as the original's oracle records, where ../shared is beside the repository.
    let oracle = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/reference/original-dungeons/paper-seeds-v0.0.2.jsonl");
    if let Ok(text) = std::fs::read_to_string(&oracle) {
        let first: serde_json::Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
        let keys = |v: &serde_json::Value| {
            let mut k: Vec<String> = v.as_object().unwrap().keys().cloned().collect();
            k.sort();
            k
        };
        assert_eq!(keys(&records[0]), keys(&first));
        assert_eq!(keys(&records[0]["rooms"][0]), keys(&first["rooms"][0]));
        let with_gold = records
            .iter()
            .find(|r| !r["gold"].as_array().unwrap().is_empty())
            .unwrap();
        assert_eq!(keys(&with_gold["gold"][0]), keys(&first["gold"][0]));
    }
    // The same seeds give the same lines.
    let again = bin()
        .args(["dump", "--seed", "1000..1003", "--floors", "3"])
        .output()
        .unwrap();
    assert_eq!(text(&again).0, out);
}

/// `dump --config` with the oracle's config under the original's seeding writes the oracle,
/// record for record: the paper's seeds 0..40 and 1000..1500, floors 1-3 (1620 records).
#[test]
fn dump_with_original_seeding_writes_the_originals_oracle() {
    let oracle = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/reference/original-dungeons/paper-seeds-v0.0.2.jsonl");
    let Ok(want) = std::fs::read_to_string(&oracle) else {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "CI must run with ../shared beside the repository: {} is missing",
            oracle.display()
        );
        return;
    };
    let want: Vec<serde_json::Value> = want
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    // The config the oracle was dumped with (its README), plus our seeding switch.
    let scratch = Scratch::new("dump_original");
    let config = scratch.file("original-seeding.json");
    std::fs::write(
        &config,
        r#"{"width":32,"height":16,"hide_dungeon":true,"seeding":"original",
            "dungeon":{"style":"rogue","room_num_x":2,"room_num_y":2},"enemies":{"enemies":[]}}"#,
    )
    .unwrap();
    let mut got = Vec::new();
    for seeds in ["0..40", "1000..1500"] {
        let o = bin()
            .args(["dump", "--config"])
            .arg(&config)
            .args(["--seed", seeds, "--floors", "3"])
            .output()
            .unwrap();
        let (out, err) = text(&o);
        assert!(o.status.success(), "{err}");
        got.extend(
            out.lines()
                .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()),
        );
    }
    std::fs::remove_file(&config).unwrap();
    assert_eq!(got.len(), 1620);
    assert_eq!(got.len(), want.len());
    let differing: Vec<_> = got
        .iter()
        .zip(&want)
        .filter(|(g, w)| g != w)
        .map(|(g, _)| (g["seed"].clone(), g["floor"].clone()))
        .collect();
    assert!(
        differing.is_empty(),
        "{} of 1620 records differ from the oracle, first (seed, floor): {:?}",
        differing.len(),
        differing.first()
    );
}
