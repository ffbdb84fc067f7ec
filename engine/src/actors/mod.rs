//! The state of each actor on a floor: the player and the monsters. Their turns are rules
//! (`crate::rules`); this module is data only, so `game` and `rules` both build on it.

mod enemy;
mod player;

pub(crate) use enemy::Enemy;
pub(crate) use player::Player;
