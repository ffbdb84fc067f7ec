//! The game rules, one file each: movement (moves, pickup, search), visibility (what the
//! player sees), combat (melee both ways), monsters (placement and their turn) and hunger (the
//! per-turn tick).

mod combat;
mod hunger;
mod monsters;
mod movement;
mod visibility;
