//! Unit tests that need the engine's internals: rules on hand-made floors and dungeon
//! generation statistics.

mod builder;
mod generation;
mod rules;
