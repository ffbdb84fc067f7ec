//! `rogue-gym play`: the game in the terminal (crossterm raw mode). vi keys `hjklyubn` move,
//! `HJKLYUBN` run, `s` searches, `>` descends, `.` rests, `q` quits. Messages are shown on row
//! 0 and the status line at the bottom, as in the original. `--save LOG` writes the action log
//! (config, seed, keys) on quit.

use std::io::{Stdout, Write, stdout};
use std::path::PathBuf;

use crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use crossterm::{cursor, execute, queue, style, terminal};
use rogue_gym_engine::{Command, EpisodeConfig, Game, GameConfig};

use crate::replay::ActionLog;

/// Arguments of `play`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Game config (JSON). Default: the default game (80x24, all monsters).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Seed. Default: the config's `seed`, else the low end of `seed_range`, else 0.
    #[arg(long)]
    seed: Option<u64>,
    /// Write the action log here on quit.
    #[arg(long)]
    save: Option<PathBuf>,
    /// Step limit (default: none).
    #[arg(long, default_value_t = u32::MAX)]
    max_steps: u32,
}

/// Raw mode + alternate screen, restored on drop (also on errors and panics that unwind).
pub(crate) struct Terminal {
    out: Stdout,
}

impl Terminal {
    pub(crate) fn enter() -> std::io::Result<Terminal> {
        terminal::enable_raw_mode()?;
        let mut out = stdout();
        execute!(out, terminal::EnterAlternateScreen, cursor::Hide)?;
        Ok(Terminal { out })
    }
}

impl Drop for Terminal {
    fn drop(&mut self) {
        let _ = execute!(self.out, cursor::Show, terminal::LeaveAlternateScreen);
        let _ = terminal::disable_raw_mode();
    }
}

/// Draws message (row 0), map and status line (last row), plus a hint line below.
pub(crate) fn draw(term: &mut Terminal, game: &Game, hint: &str) -> std::io::Result<()> {
    let out = &mut term.out;
    queue!(out, terminal::Clear(terminal::ClearType::All))?;
    let h = game.height();
    for (y, row) in game.screen_rows().enumerate() {
        let text = if y == 0 {
            game.message().to_string()
        } else if y == h - 1 {
            game.status_line()
        } else {
            String::from_utf8_lossy(row).into_owned()
        };
        queue!(out, cursor::MoveTo(0, y as u16), style::Print(text))?;
    }
    let end = if game.info().died {
        "  --  you died (q quits)"
    } else if game.info().won {
        "  --  you won! (q quits)"
    } else if game.is_over() {
        "  --  out of steps (q quits)"
    } else {
        ""
    };
    queue!(
        out,
        cursor::MoveTo(0, h as u16),
        style::Print(format!("{hint}{end}"))
    )?;
    out.flush()
}

pub(crate) fn run(args: Args) -> Result<(), String> {
    let config = crate::load_config(args.config.as_deref(), GameConfig::default())?;
    let mut game = Game::new(
        &config,
        EpisodeConfig {
            max_steps: args.max_steps,
            ..EpisodeConfig::default()
        },
    )
    .map_err(|e| e.to_string())?;
    let seed = args.seed.unwrap_or_else(|| game.default_seed());
    game.reset(seed);
    let mut keys: Vec<String> = Vec::new();
    {
        let mut term = Terminal::enter().map_err(|e| format!("terminal: {e}"))?;
        let hint = "hjklyubn move, HJKLYUBN run, s search, > descend, . rest, q quit";
        loop {
            draw(&mut term, &game, hint).map_err(|e| e.to_string())?;
            let ev = event::read().map_err(|e| e.to_string())?;
            let Event::Key(k) = ev else { continue };
            if k.kind != KeyEventKind::Press {
                continue;
            }
            let c = match k.code {
                KeyCode::Char('c') if k.modifiers.contains(KeyModifiers::CONTROL) => break,
                KeyCode::Char('q') | KeyCode::Esc => break,
                KeyCode::Char(c) => c,
                KeyCode::Left => 'h',
                KeyCode::Right => 'l',
                KeyCode::Up => 'k',
                KeyCode::Down => 'j',
                _ => continue,
            };
            if game.is_over() {
                continue;
            }
            if let Some(cmd) = Command::from_key(c) {
                game.step_command(cmd);
                keys.push(c.to_string());
            }
        }
    }
    println!("{}", game.status_line());
    if let Some(path) = args.save {
        let log = ActionLog {
            config,
            seed,
            max_steps: args.max_steps,
            actions: keys,
        };
        let json = serde_json::to_string_pretty(&log).map_err(|e| e.to_string())?;
        std::fs::write(&path, json).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        println!("saved {} actions to {}", log.actions.len(), path.display());
    }
    Ok(())
}
