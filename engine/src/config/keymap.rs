//! Key bindings of the original's JSON keymap (docs/rules.md §1). Only used by terminal play.

use serde::{Deserialize, Serialize};

/// A direction name as written in keymaps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[allow(missing_docs)]
pub enum KeyDirection {
    Up,
    Down,
    Left,
    Right,
    LeftUp,
    RightUp,
    LeftDown,
    RightDown,
}

/// A game action in a keymap: `"DownStair"`, `{"Move": "Left"}`, `{"MoveUntil": "Up"}`, ...
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum KeyAction {
    /// One step.
    Move(KeyDirection),
    /// Run until something interesting happens.
    MoveUntil(KeyDirection),
    /// Not implemented in the original either; ignored.
    UpStair,
    /// Descend.
    DownStair,
    /// Search the 8 neighbours.
    Search,
    /// Rest one turn.
    NoOp,
}

/// A system command in a keymap.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[allow(missing_docs)]
pub enum SysCode {
    Cancel,
    Continue,
    Enter,
    Inventory,
    No,
    Save,
    Quit,
    Yes,
}

/// What a key does: `{"Act": ..}`, `{"Sys": ..}` or `{"Both": {"act": .., "sys": ..}}`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum InputCode {
    /// A game action.
    Act(KeyAction),
    /// A system command.
    Sys(SysCode),
    /// Both (e.g. `y` = move LeftUp or answer yes).
    Both {
        /// The game action.
        act: KeyAction,
        /// The system command.
        sys: SysCode,
    },
}

/// Parses a key name: a single character, a named key, `F<n>`, `Alt+<c>` or `Ctrl+<c>`.
pub(crate) fn parse_key(s: &str) -> Option<()> {
    const NAMED: [&str; 13] = [
        "Left",
        "Right",
        "Up",
        "Down",
        "Esc",
        "Backspace",
        "Home",
        "End",
        "PageUp",
        "PageDown",
        "Delete",
        "Insert",
        "Null",
    ];
    let mut chars = s.chars();
    if let (Some(_), None) = (chars.next(), chars.next()) {
        return Some(());
    }
    if NAMED.contains(&s) {
        return Some(());
    }
    if let Some(n) = s.strip_prefix('F') {
        return n
            .parse::<u8>()
            .ok()
            .filter(|n| (1..=12).contains(n))
            .map(|_| ());
    }
    for prefix in ["Alt+", "Ctrl+"] {
        if let Some(c) = s.strip_prefix(prefix) {
            return (c.chars().count() == 1).then_some(());
        }
    }
    None
}
