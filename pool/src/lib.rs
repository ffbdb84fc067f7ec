//! The Rogue-Gym environment pool (work in progress).
