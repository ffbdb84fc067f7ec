//! The registry of env kinds: builds an env from its JSON spec by its `"kind"` field. The
//! built-in kinds are registered by [`EnvRegistry::with_defaults`] at the crate root.

use std::ops::Range;

use serde_json::Value;

use crate::env::{Env, EnvBlock, EnvError};

/// Builds an env from its JSON spec (the whole object, including `"kind"`) and its global
/// index in the pool (kinds that build each env differently, such as hosted envs with one
/// callable per env, use it; `0` for the supervisor's probe).
pub type EnvCtor = fn(&Value, u64) -> Result<Box<dyn Env>, EnvError>;

/// Builds a worker's whole block of envs, the envs `envs` (global indices) of the pool, from
/// its JSON spec (see [`EnvBlock`]).
pub type BlockCtor = fn(&Value, Range<u64>) -> Result<Box<dyn EnvBlock>, EnvError>;

/// Runs the whole life of a worker's env thread (`body`), in a scope the kinds need there:
/// the extension's keeps the thread's Python thread state for the thread's life, so that each
/// env call does not make and free one (see [`EnvRegistry::set_thread_scope`]).
pub type ThreadScope = fn(body: &mut (dyn FnMut() + Send));

/// How a kind builds its envs.
#[derive(Debug, Clone, Copy)]
enum Ctor {
    Env(EnvCtor),
    Block(BlockCtor),
}

/// What a worker builds for its block: one env per index, or one block of them.
pub enum Built {
    /// One [`Env`] per env of the block.
    Envs(Vec<Box<dyn Env>>),
    /// The whole block as one [`EnvBlock`].
    Block(Box<dyn EnvBlock>),
}

/// The env kinds a worker (and the supervisor, to learn the spec) can build, by name. The JSON
/// spec of an env is an object whose `"kind"` field selects the constructor, e.g.
/// `{"kind": "rogue", "config": {...}, "max_steps": 500}`.
#[derive(Debug, Clone, Default)]
pub struct EnvRegistry {
    kinds: Vec<(String, Ctor)>,
    thread_scope: Option<ThreadScope>,
}

impl EnvRegistry {
    /// An empty registry.
    pub fn new() -> Self {
        Self::default()
    }
    /// Add (or replace) a kind.
    pub fn register(&mut self, kind: &str, ctor: EnvCtor) {
        self.insert(kind, Ctor::Env(ctor));
    }
    /// Add (or replace) a kind whose worker builds its whole block as one [`EnvBlock`]. Such a
    /// kind's spec must be given to the pool ([`crate::PoolConfig::spec`]): there is no single
    /// env to probe.
    pub fn register_block(&mut self, kind: &str, ctor: BlockCtor) {
        self.insert(kind, Ctor::Block(ctor));
    }
    fn insert(&mut self, kind: &str, ctor: Ctor) {
        self.kinds.retain(|(k, _)| k != kind);
        self.kinds.push((kind.to_string(), ctor));
    }
    /// Run each env thread of a worker (`WorkerConfig::env_threads`) inside `scope`.
    pub fn set_thread_scope(&mut self, scope: ThreadScope) {
        self.thread_scope = Some(scope);
    }
    /// The scope env threads run in ([`EnvRegistry::set_thread_scope`]), if one was set.
    pub fn thread_scope(&self) -> Option<ThreadScope> {
        self.thread_scope
    }
    /// The registered kinds.
    pub fn kinds(&self) -> Vec<&str> {
        self.kinds.iter().map(|(k, _)| k.as_str()).collect()
    }
    fn ctor<'a>(&self, spec: &'a Value) -> Result<(&'a str, Ctor), EnvError> {
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
        Ok((kind, *ctor))
    }
    /// Build env number `index` of a pool from its JSON spec.
    pub fn make(&self, spec: &Value, index: u64) -> Result<Box<dyn Env>, EnvError> {
        match self.ctor(spec)? {
            (_, Ctor::Env(ctor)) => {
                let env = ctor(spec, index)?;
                env.spec().validate()?;
                Ok(env)
            }
            (kind, Ctor::Block(_)) => Err(EnvError::new(format!(
                "env kind {kind:?} builds whole blocks of envs, not single ones: give the pool \
                 its spec"
            ))),
        }
    }
    /// Whether the spec's kind builds whole blocks of envs (a vector env per worker) rather
    /// than single envs (false for a spec of no known kind: building it will say why).
    pub fn builds_blocks(&self, spec: &Value) -> bool {
        matches!(self.ctor(spec), Ok((_, Ctor::Block(_))))
    }
    /// Build the envs `envs` (global indices) of a worker's block from their JSON spec.
    /// `on_env` is told each env's index before it is built, so that a failure can be blamed on
    /// it (a block's failure is blamed on its first env).
    pub fn make_block(
        &self,
        spec: &Value,
        envs: Range<u64>,
        mut on_env: impl FnMut(u64),
    ) -> Result<Built, EnvError> {
        match self.ctor(spec)? {
            (_, Ctor::Env(ctor)) => {
                let mut built = Vec::with_capacity(envs.clone().count());
                for index in envs {
                    on_env(index);
                    let env = ctor(spec, index)?;
                    env.spec().validate()?;
                    built.push(env);
                }
                Ok(Built::Envs(built))
            }
            (_, Ctor::Block(ctor)) => {
                on_env(envs.start);
                let block = ctor(spec, envs)?;
                block.spec().validate()?;
                Ok(Built::Block(block))
            }
        }
    }
}
