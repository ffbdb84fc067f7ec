//! The 11 RL actions (the original's order `. h j k l n b u y > s`) and the terminal-play
//! commands (the same plus runs).

use crate::geometry::Dir;

/// Number of RL actions.
pub const NUM_ACTIONS: usize = 11;

/// One RL action. The discriminant is the action index.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Action {
    /// `.`: rest one turn (hunger and monsters advance).
    NoOp = 0,
    /// `h`: x-1.
    Left = 1,
    /// `j`: y+1.
    Down = 2,
    /// `k`: y-1.
    Up = 3,
    /// `l`: x+1.
    Right = 4,
    /// `n`: x+1, y+1.
    RightDown = 5,
    /// `b`: x-1, y+1.
    LeftDown = 6,
    /// `u`: x+1, y-1.
    RightUp = 7,
    /// `y`: x-1, y-1.
    LeftUp = 8,
    /// `>`: descend when standing on the stairs.
    DownStair = 9,
    /// `s`: search the 8 neighbours for hidden passages and secret doors.
    Search = 10,
}

/// The key of each action, in index order (the original's order): `j` moves down, `k` up.
pub const ACTION_KEYS: &str = ".hjklnbuy>s";

const _: () = assert!(ACTION_KEYS.len() == NUM_ACTIONS);

impl Action {
    /// All actions in index order.
    pub const ALL: [Action; NUM_ACTIONS] = [
        Action::NoOp,
        Action::Left,
        Action::Down,
        Action::Up,
        Action::Right,
        Action::RightDown,
        Action::LeftDown,
        Action::RightUp,
        Action::LeftUp,
        Action::DownStair,
        Action::Search,
    ];

    /// The action with this index (0..11).
    pub fn from_index(i: usize) -> Option<Action> {
        Action::ALL.get(i).copied()
    }

    /// The action of a key: one of `. h j k l n b u y > s`.
    pub fn from_key(c: char) -> Option<Action> {
        ACTION_KEYS.find(c).map(|i| Action::ALL[i])
    }

    /// This action's key.
    pub fn key(self) -> char {
        ACTION_KEYS.as_bytes()[self as usize] as char
    }

    /// This action's index.
    pub fn index(self) -> usize {
        self as usize
    }

    /// The direction of a move action.
    pub(crate) fn dir(self) -> Option<Dir> {
        Some(match self {
            Action::Left => Dir::Left,
            Action::Down => Dir::Down,
            Action::Up => Dir::Up,
            Action::Right => Dir::Right,
            Action::RightDown => Dir::RightDown,
            Action::LeftDown => Dir::LeftDown,
            Action::RightUp => Dir::RightUp,
            Action::LeftUp => Dir::LeftUp,
            _ => return None,
        })
    }
}

impl TryFrom<u8> for Action {
    type Error = u8;
    /// The action with this index; the index itself as the error when it is >= 11.
    fn try_from(i: u8) -> Result<Action, u8> {
        Action::from_index(usize::from(i)).ok_or(i)
    }
}

/// A terminal-play command: an RL action, or a run (`HJKLYUBN`) in a move action's direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// One RL action.
    Act(Action),
    /// Run: repeat the move until something interesting happens. The field is a move action.
    Run(Action),
}

impl Command {
    /// Parses a key: the 11 action keys, or uppercase `HJKLYUBN` for runs.
    pub fn from_key(c: char) -> Option<Command> {
        if let Some(a) = Action::from_key(c) {
            return Some(Command::Act(a));
        }
        if c.is_ascii_uppercase()
            && let Some(a) = Action::from_key(c.to_ascii_lowercase())
            && a.dir().is_some()
        {
            return Some(Command::Run(a));
        }
        None
    }

    /// The key of this command (uppercase for runs).
    pub fn key(self) -> char {
        match self {
            Command::Act(a) => a.key(),
            Command::Run(a) => a.key().to_ascii_uppercase(),
        }
    }
}
