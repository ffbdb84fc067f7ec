//! The terminal screen shared by `play` and `replay`: raw mode and the alternate screen
//! ([`Terminal`]), and drawing a game ([`draw`]).

use std::io::{Stdout, Write, stdout};

use crossterm::{cursor, execute, queue, style, terminal};
use rogue_gym_engine::Game;

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
