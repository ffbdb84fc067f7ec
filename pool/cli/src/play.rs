//! `rogue-gym play`: the game in the terminal (crossterm raw mode). vi keys `hjklyubn` move,
//! `HJKLYUBN` run, `s` searches, `>` descends, `.` rests, `q` quits (a config `keymap`
//! replaces these keys; Esc always quits). Messages are shown on row
//! 0 and the status line at the bottom, as in the original. On quit the action log (config,
//! seed, keys) is written to `--save LOG` (default `rogue-gym-actions.json`; `--no-save` skips
//! it).

use std::path::PathBuf;

use crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use rogue_gym_engine::config::{InputCode, KeyAction, KeyDirection, SysCode};
use rogue_gym_engine::{Action, Command, EpisodeConfig, Game, GameConfig};

use crate::action_log::ActionLog;
use crate::terminal::{Terminal, draw};

/// Arguments of `play`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Game config (JSON). Default: the default game (80x24, all monsters).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Seed. Default: the config's `seed`, else the low end of `seed_range`, else 0.
    #[arg(long)]
    seed: Option<u64>,
    /// Where the action log is written on quit (replay it with `rogue-gym replay`).
    #[arg(long, default_value = "rogue-gym-actions.json")]
    save: PathBuf,
    /// Do not write the action log.
    #[arg(long)]
    no_save: bool,
    /// Step limit (default: none).
    #[arg(long, default_value_t = u32::MAX)]
    max_steps: u32,
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
                KeyCode::Char('q') if config.keymap.is_none() => break,
                KeyCode::Esc => break,
                KeyCode::Char(c) => c,
                KeyCode::Left => 'h',
                KeyCode::Right => 'l',
                KeyCode::Up => 'k',
                KeyCode::Down => 'j',
                _ => continue,
            };
            let cmd = match key_command(&config, c) {
                Some(KeyResult::Quit) => break,
                Some(KeyResult::Cmd(cmd)) => cmd,
                None => continue,
            };
            if game.is_over() {
                continue;
            }
            game.step_command(cmd);
            // The log stores the command's canonical key, so replay needs no keymap.
            keys.push(cmd.key().to_string());
        }
    }
    println!("{}", game.status_line());
    if !args.no_save {
        let path = args.save;
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

/// What a key does in play.
enum KeyResult {
    Cmd(Command),
    Quit,
}

/// Maps a key through the config's keymap when it has one, else the built-in vi keys.
fn key_command(config: &GameConfig, c: char) -> Option<KeyResult> {
    let Some(keymap) = &config.keymap else {
        return Command::from_key(c).map(KeyResult::Cmd);
    };
    let act = match keymap.get(&c.to_string())? {
        InputCode::Act(a) | InputCode::Both { act: a, .. } => *a,
        InputCode::Sys(SysCode::Quit) => return Some(KeyResult::Quit),
        InputCode::Sys(_) => return None,
    };
    let dir_action = |d: KeyDirection| match d {
        KeyDirection::Up => Action::Up,
        KeyDirection::Down => Action::Down,
        KeyDirection::Left => Action::Left,
        KeyDirection::Right => Action::Right,
        KeyDirection::LeftUp => Action::LeftUp,
        KeyDirection::RightUp => Action::RightUp,
        KeyDirection::LeftDown => Action::LeftDown,
        KeyDirection::RightDown => Action::RightDown,
    };
    let cmd = match act {
        KeyAction::Move(d) => Command::Act(dir_action(d)),
        KeyAction::MoveUntil(d) => Command::Run(dir_action(d)),
        KeyAction::DownStair => Command::Act(Action::DownStair),
        KeyAction::Search => Command::Act(Action::Search),
        KeyAction::NoOp => Command::Act(Action::NoOp),
        KeyAction::UpStair => return None,
    };
    Some(KeyResult::Cmd(cmd))
}
