//! The action log written by `play` and read by `replay`: the config, the seed, the step
//! limit and the keys pressed.

use rogue_gym_engine::{Command, GameConfig};
use serde::{Deserialize, Serialize};

/// An action log: the config, the seed, the step limit and the keys pressed.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ActionLog {
    /// The game config.
    pub config: GameConfig,
    /// The episode seed.
    pub seed: u64,
    /// The step limit the game ran with.
    #[serde(default = "default_max_steps")]
    pub max_steps: u32,
    /// One key per command: `. h j k l n b u y > s`, or `HJKLYUBN` for runs.
    pub actions: Vec<String>,
}

fn default_max_steps() -> u32 {
    u32::MAX
}

/// Parses a log's keys into commands.
pub(crate) fn commands(log: &ActionLog) -> Result<Vec<Command>, String> {
    log.actions
        .iter()
        .enumerate()
        .map(|(i, k)| {
            let mut chars = k.chars();
            match (chars.next(), chars.next()) {
                (Some(c), None) => {
                    Command::from_key(c).ok_or_else(|| format!("action {i}: unknown key {k:?}"))
                }
                _ => Err(format!("action {i}: {k:?} is not a single key")),
            }
        })
        .collect()
}
