//! The player's state.

/// The player's state.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Player {
    pub pos: usize,
    pub hp: i32,
    pub max_hp: i32,
    pub str_cur: i32,
    pub str_max: i32,
    pub level: u32,
    pub exp: u32,
    pub food: u32,
    pub quiet: u32,
    pub gold: u32,
    pub defense: i32,
    pub weapon: (u32, u32),
    pub hit_plus: i32,
    pub dam_plus: i32,
}
