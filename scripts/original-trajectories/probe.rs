//! Plays a key string on the original Rogue-Gym runtime (v0.0.2's `rogue-gym-core`, built from
//! its tag; see README.md) and prints, before the first key and after each key, one line:
//! `gold <TAB> floor <TAB> screen rows joined by \x01`. Only the original's public API is used.
use rogue_gym_core::dungeon::Positioned;
use rogue_gym_core::input::Key;
use rogue_gym_core::{GameConfig, RunTime};

fn print_state(rt: &RunTime) {
    let (w, h) = rt.screen_size();
    let mut rows = vec![vec![b' '; w.0 as usize]; h.0 as usize];
    rt.draw_screen(|Positioned(cd, tile)| {
        rows[cd.y.0 as usize][cd.x.0 as usize] = tile.to_byte();
        Ok(())
    })
    .expect("the original draws its screen");
    let rows: Vec<String> = rows
        .into_iter()
        .map(|r| String::from_utf8(r).expect("ASCII tiles"))
        .collect();
    let status = rt.player_status();
    println!("{}\t{}\t{}", status.gold, status.dungeon_level, rows.join("\u{1}"));
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 3 {
        eprintln!("usage: probe CONFIG.json KEYS");
        std::process::exit(2);
    }
    let config = std::fs::read_to_string(&args[1]).expect("a readable config file");
    let mut rt = GameConfig::from_json(&config)
        .and_then(|c| c.build())
        .expect("a config the original accepts");
    print_state(&rt);
    for c in args[2].chars() {
        // A refused key (a blocked move...) is part of play; the state is printed anyway.
        let _ = rt.react_to_key(Key::Char(c));
        print_state(&rt);
    }
}
