//! Waiting and locking with the GIL in mind: a long wait of the pool runs Python's signal
//! handlers now and then, and a lock another thread may hold through such a wait is taken with
//! the GIL released.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError, TryLockError};

use pyo3::prelude::*;
use rogue_gym_pool::InterruptCheck;

/// The pool's interrupt check: between the slices of a long wait (GIL released), re-acquire
/// the GIL briefly and run Python's signal handlers; an exception (KeyboardInterrupt from
/// Ctrl-C) is kept in `slot` and aborts the wait.
pub(crate) fn interrupt_check(slot: Arc<Mutex<Option<PyErr>>>) -> InterruptCheck {
    Box::new(move || {
        Python::attach(|py| match py.check_signals() {
            Ok(()) => false,
            Err(e) => {
                if let Ok(mut s) = slot.lock() {
                    *s = Some(e);
                }
                true
            }
        })
    })
}

/// Lock `m` from a thread that holds the GIL, waiting with the GIL released: another thread
/// may hold `m` through a long wait that takes the GIL now and then (the interrupt check), so
/// waiting for `m` with the GIL held could deadlock both. A lock poisoned by a panic is taken
/// all the same: the pool's calls catch their panics ([`rogue_gym_pool::Pool::guarded`]), so
/// what it guards is whole, and `close()` must always get through.
pub(crate) fn lock_gil_free<'a, T: Send>(
    py: Python<'_>,
    m: &'a Mutex<T>,
) -> PyResult<MutexGuard<'a, T>> {
    loop {
        match m.try_lock() {
            Ok(g) => return Ok(g),
            Err(TryLockError::WouldBlock) => py.detach(|| drop(m.lock())),
            Err(TryLockError::Poisoned(p)) => return Ok(p.into_inner()),
        }
    }
}

/// Lock `m` (without the GIL), taking it even if a panic poisoned it (see [`lock_gil_free`]).
pub(crate) fn lock_any<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}
