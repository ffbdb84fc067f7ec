//! A monster's state.

/// One monster on the current floor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Enemy {
    /// Index into `Game::kinds`.
    pub kind: u16,
    pub pos: usize,
    pub hp: i32,
    pub level: u32,
    pub defense: i32,
    pub exp: u32,
    pub awake: bool,
    pub alive: bool,
}
