//! The worker's side of the extension: what a pool worker process (`python -m
//! rogue_gym.worker`) runs to host envs written in Python, one gymnasium env per row
//! ([`hosted`]) or one vector env per worker block ([`hosted_vector`]). The rest of the crate
//! is the caller's binding (the `Pool` class and its calls).

pub(crate) mod hosted;
pub(crate) mod hosted_vector;
