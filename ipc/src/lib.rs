//! Shared-memory transport for the Rogue-Gym pool (work in progress).
