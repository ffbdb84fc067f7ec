//! The env kinds built into the pool. Each module owns one kind and its constructor; the
//! crate root registers them ([`crate::EnvRegistry::with_defaults`]).

pub mod rogue;
pub mod test_env;
