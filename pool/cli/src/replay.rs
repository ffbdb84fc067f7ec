//! `rogue-gym replay LOG`: plays an action log back, animated in the terminal, or (with
//! `--no-tty`, or when stdout is not a terminal) straight to the end, printing the final
//! screen, the status line and a summary.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::time::Duration;

use crossterm::event::{self, Event, KeyCode, KeyEventKind};
use rogue_gym_engine::{EpisodeConfig, Game};

use crate::action_log::{ActionLog, commands};
use crate::terminal::{Terminal, draw};

/// Arguments of `replay`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The action log (JSON written by `play --save`).
    log: PathBuf,
    /// Delay between steps when animating.
    #[arg(long, default_value_t = 100)]
    interval_ms: u64,
    /// Do not animate: print the final screen, status and a summary.
    #[arg(long)]
    no_tty: bool,
}

pub(crate) fn run(args: Args) -> Result<(), String> {
    let text = std::fs::read_to_string(&args.log)
        .map_err(|e| format!("cannot read log {}: {e}", args.log.display()))?;
    let log: ActionLog =
        serde_json::from_str(&text).map_err(|e| format!("log {}: {e}", args.log.display()))?;
    log.config
        .validate()
        .map_err(|e| format!("log {}: config: {e}", args.log.display()))?;
    let cmds = commands(&log)?;
    let mut game = Game::new(
        &log.config,
        EpisodeConfig {
            max_steps: log.max_steps,
            ..EpisodeConfig::default()
        },
    )
    .map_err(|e| format!("log {}: config: {e}", args.log.display()))?;
    game.reset(log.seed);
    let mut total = 0.0f64;
    if args.no_tty || !std::io::stdout().is_terminal() {
        for c in cmds {
            total += f64::from(game.step_command(c).reward);
        }
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{}", game.message());
        for row in game.screen_rows().skip(1).take(game.height() - 2) {
            let _ = writeln!(out, "{}", String::from_utf8_lossy(row));
        }
        let _ = writeln!(out, "{}", game.status_line());
        let _ = writeln!(out, "{}", summary(&game, total));
        return Ok(());
    }
    let mut term = Terminal::enter().map_err(|e| format!("terminal: {e}"))?;
    draw(&mut term, &game, "replay: q quits").map_err(|e| e.to_string())?;
    for c in cmds {
        total += f64::from(game.step_command(c).reward);
        draw(&mut term, &game, "replay: q quits").map_err(|e| e.to_string())?;
        if event::poll(Duration::from_millis(args.interval_ms)).unwrap_or(false)
            && let Ok(Event::Key(k)) = event::read()
            && k.kind == KeyEventKind::Press
            && matches!(k.code, KeyCode::Char('q') | KeyCode::Esc)
        {
            break;
        }
    }
    draw(&mut term, &game, "replay finished: press any key").map_err(|e| e.to_string())?;
    loop {
        match event::read() {
            Ok(Event::Key(k)) if k.kind == KeyEventKind::Press => break,
            Ok(_) => {}
            Err(_) => break,
        }
    }
    drop(term);
    println!("{}", summary(&game, total));
    Ok(())
}

/// One-line episode summary.
pub(crate) fn summary(game: &Game, total_reward: f64) -> String {
    let i = game.info();
    format!(
        "seed {} steps {} reward {} floor {} max_floor {} gold {} hp {}/{} died {} won {}",
        i.seed, i.steps, total_reward, i.floor, i.max_floor, i.gold, i.hp, i.max_hp, i.died, i.won
    )
}
