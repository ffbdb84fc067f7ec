//! # rogue-gym-engine
//!
//! The Rogue-Gym game (a rebuild of Kanagawa & Kaneko's roguelike RL benchmark, CoG 2019):
//! configuration, "rogue"-style dungeon generation, the rules, and observation encoders.
//!
//! This crate is the game and nothing else: it knows nothing of IPC, processes or Python.
//! The environment pool (`rogue-gym-pool`) owns many [`Game`]s in worker processes, and each
//! step asks a game to write its observation straight into a caller-provided buffer
//! ([`ObsBufMut`]) - in practice a loaned shared-memory sample - so there is no intermediate
//! copy.
//!
//! ```
//! use rogue_gym_engine::{Action, EpisodeConfig, Game, GameConfig, ObsBufMut, ObsSpec};
//! let mut game = Game::new(&GameConfig::paper(), EpisodeConfig { max_steps: 500, ..Default::default() }).unwrap();
//! game.reset(7);
//! let spec = ObsSpec::paper();
//! let mut obs = vec![0u8; game.observation_shape(&spec).iter().product()];
//! let r = game.step(Action::Right);
//! game.write_obs(&spec, ObsBufMut::U8(&mut obs)).unwrap();
//! assert!(!r.terminated);
//! ```
//!
//! Determinism: the same config, seed and actions give the same game. Every subsystem
//! draws from its own ChaCha8 stream derived from the seed (floor k's layout from (seed, k)),
//! there is no `HashMap` iteration and no float in the game logic.

#![deny(missing_docs)]

pub mod action;
pub mod config;
pub mod dump;
mod dungeon;
pub mod game;
pub mod geometry;
pub mod obs;

mod actors;
mod rng;
mod rules;
mod symbol;

#[cfg(test)]
mod tests;

pub use action::{ACTION_KEYS, Action, Command, NUM_ACTIONS};

/// The version of the games this engine plays, as benchmark results record it: raised by one
/// whenever any seed's dungeon or any rule changes (whatever changes what an episode plays),
/// so that scores of different versions are never mixed. `tests/determinism.rs` holds a digest
/// of games played under each version: a change that alters them fails there until this is
/// raised and the digest recorded beside it. The CHANGELOG says what each version changed.
pub const ENGINE_VERSION: u32 = 1;
pub use config::{ConfigError, GameConfig};
pub use dump::{FloorRecord, floor_records};
pub use game::{EpisodeConfig, EpisodeInfo, Game, StepResult};
pub use obs::{Dtype, Encoding, ObsBufMut, ObsError, ObsSpec, Status, StatusFlags};
pub use rng::splitmix64;

/// A `Game` moves between threads (pool workers may own games on worker threads).
const _: () = {
    const fn assert_send<T: Send + Sync>() {}
    assert_send::<Game>();
};
pub mod summary;
pub use summary::{FloorSummary, floor_summary};
