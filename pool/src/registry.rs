//! The registry of env kinds: builds an env from its JSON spec by its `"kind"` field. The
//! built-in kinds are registered by [`EnvRegistry::with_defaults`] at the crate root.

use serde_json::Value;

use crate::env::{Env, EnvError};

/// Builds an env from its JSON spec (the whole object, including `"kind"`) and its global
/// index in the pool (kinds that build each env differently, such as hosted envs with one
/// callable per env, use it; `0` for the supervisor's probe).
pub type EnvCtor = fn(&Value, u64) -> Result<Box<dyn Env>, EnvError>;

/// The env kinds a worker (and the supervisor, to learn the spec) can build, by name. The JSON
/// spec of an env is an object whose `"kind"` field selects the constructor, e.g.
/// `{"kind": "rogue", "config": {...}, "max_steps": 500}`.
#[derive(Debug, Clone, Default)]
pub struct EnvRegistry {
    kinds: Vec<(String, EnvCtor)>,
}

impl EnvRegistry {
    /// An empty registry.
    pub fn new() -> Self {
        Self::default()
    }
    /// Add (or replace) a kind.
    pub fn register(&mut self, kind: &str, ctor: EnvCtor) {
        self.kinds.retain(|(k, _)| k != kind);
        self.kinds.push((kind.to_string(), ctor));
    }
    /// The registered kinds.
    pub fn kinds(&self) -> Vec<&str> {
        self.kinds.iter().map(|(k, _)| k.as_str()).collect()
    }
    /// Build env number `index` of a pool from its JSON spec.
    pub fn make(&self, spec: &Value, index: u64) -> Result<Box<dyn Env>, EnvError> {
        let kind = spec.get("kind").and_then(Value::as_str).ok_or_else(|| {
            EnvError::new(format!(
                "env spec must be a JSON object with a \"kind\" string (one of {:?}); got {spec}",
                self.kinds()
            ))
        })?;
        let (_, ctor) = self.kinds.iter().find(|(k, _)| k == kind).ok_or_else(|| {
            EnvError::new(format!(
                "unknown env kind {kind:?}; known kinds: {:?}",
                self.kinds()
            ))
        })?;
        let env = ctor(spec, index)?;
        env.spec().validate()?;
        Ok(env)
    }
}
