//! The Rogue-Gym game as a pool [`Env`] (adapter over `rogue-gym-engine`).

use serde_json::Value;

use crate::env::{Env, EnvError};

/// [`crate::EnvCtor`] of the `"rogue"` kind.
pub fn make_rogue_env(_v: &Value) -> Result<Box<dyn Env>, EnvError> {
    Err(EnvError::new("the rogue env kind is not available yet"))
}
