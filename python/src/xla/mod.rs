//! Jit-able stepping for JAX (`rogue_gym.xla`): two XLA FFI handlers, `rogue_gym_send` and
//! `rogue_gym_recv`, that step a pool from inside compiled code with no Python on the way.
//!
//! A pool opts in with `Pool.xla_key()`, which registers an [`XlaTarget`] (a weak reference to
//! the pool and the handlers' own state) under a small integer key. The key is the `handle`
//! array that the jitted functions pass along: `send(handle, action, env_id)` returns it and
//! `recv(handle)` takes it, so the data dependency orders the calls, and the calls are
//! declared side-effecting so that XLA neither drops nor merges them. The handlers read the
//! call frame ([`ffi`]), find the target by key and run the pool's own calls ([`target`]).

use std::collections::HashMap;
use std::ffi::c_void;
use std::sync::atomic::{AtomicI32, Ordering};
use std::sync::{Arc, LazyLock, Mutex};

use pyo3::prelude::*;
use pyo3::types::PyDict;

mod ffi;
mod handlers;
mod target;

pub(crate) use target::XlaTarget;

/// The registered targets, by key.
static TARGETS: LazyLock<Mutex<HashMap<i32, Arc<XlaTarget>>>> =
    LazyLock::new(|| Mutex::new(HashMap::new()));
static NEXT_KEY: AtomicI32 = AtomicI32::new(1);

/// Register `target` and return its key.
pub(crate) fn register(target: XlaTarget) -> i32 {
    let key = NEXT_KEY.fetch_add(1, Ordering::Relaxed);
    if let Ok(mut t) = TARGETS.lock() {
        t.insert(key, Arc::new(target));
    }
    key
}

/// Forget the target of `key` (its pool closed).
pub(crate) fn unregister(key: i32) {
    if let Ok(mut t) = TARGETS.lock() {
        t.remove(&key);
    }
}

fn lookup(key: i32) -> Option<Arc<XlaTarget>> {
    TARGETS.lock().ok()?.get(&key).cloned()
}

/// The FFI handlers as `{name: capsule}`, for `jax.ffi.register_ffi_target(name, capsule,
/// platform="cpu")`: `rogue_gym_send` and `rogue_gym_recv`.
#[pyfunction]
pub(crate) fn xla_handlers(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    let pairs: [(&str, handlers::Handler); 2] = [
        ("rogue_gym_send", handlers::rogue_gym_send),
        ("rogue_gym_recv", handlers::rogue_gym_recv),
    ];
    for (name, f) in pairs {
        // SAFETY: a capsule of a function pointer with no name and no destructor, as
        // `jax.ffi.pycapsule` makes; the function lives as long as the extension.
        let capsule = unsafe {
            let ptr = pyo3::ffi::PyCapsule_New(f as *mut c_void, std::ptr::null(), None);
            Bound::from_owned_ptr_or_err(py, ptr)?
        };
        d.set_item(name, capsule)?;
    }
    Ok(d)
}
