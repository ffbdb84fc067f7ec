//! `"seeding": "original"` reproduces the original's dungeons (v0.0.2) seed for seed: every
//! record of the oracle in `../shared/reference/original-dungeons/` (read in place, never
//! copied), floors 1-3 of the paper's seeds, equals ours field for field.

use std::path::PathBuf;

use rogue_gym_engine::config::Seeding;
use rogue_gym_engine::{FloorRecord, GameConfig, floor_records};

/// The oracle's records, or `None` (skip) outside CI when `../shared` is absent.
fn oracle() -> Option<Vec<FloorRecord>> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/reference/original-dungeons/paper-seeds-v0.0.2.jsonl");
    let Ok(text) = std::fs::read_to_string(&path) else {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "CI must run with ../shared beside the repository: {} is missing",
            path.display()
        );
        eprintln!("skipped: {} is missing", path.display());
        return None;
    };
    Some(
        text.lines()
            .map(|l| serde_json::from_str(l).expect("an oracle record"))
            .collect(),
    )
}

/// The oracle's config: the paper's, with the original's seeding.
fn original_paper() -> GameConfig {
    GameConfig {
        seeding: Seeding::Original,
        ..GameConfig::paper()
    }
}

#[test]
fn every_oracle_floor_is_reproduced() {
    let Some(oracle) = oracle() else {
        return;
    };
    assert_eq!(oracle.len(), 1620, "the oracle holds 540 seeds x 3 floors");
    let cfg = original_paper();
    let mut mismatches = Vec::new();
    for want in oracle.iter().filter(|r| r.floor == 1) {
        let ours = floor_records(&cfg, want.seed, 3).unwrap();
        for got in ours {
            let want = oracle
                .iter()
                .find(|r| r.seed == got.seed && r.floor == got.floor)
                .expect("the oracle has floors 1-3 of each seed");
            if &got != want {
                mismatches.push((got, want.clone()));
            }
        }
    }
    if let Some((got, want)) = mismatches.first() {
        let show = |r: &FloorRecord| r.map.join("\n");
        panic!(
            "{} of 1620 records differ; first: seed {} floor {}\nours:\n{}\n{:?}\noriginal:\n{}\n{:?}",
            mismatches.len(),
            got.seed,
            got.floor,
            show(got),
            FloorRecord {
                map: vec![],
                ..got.clone()
            },
            show(want),
            FloorRecord {
                map: vec![],
                ..want.clone()
            },
        );
    }
}
