//! The Rogue-Gym game engine (work in progress).
