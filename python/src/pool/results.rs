//! Every call's result in one form: the per-env values decoded into a preallocated column
//! buffer (one per shared batch slot for whole-batch calls, one more for `recv`), a summary
//! (`SUMMARY_*` bits), and the extra info of the envs that wrote some, joined into one bytes
//! object (hosted envs' infos), all from the same native call.

use std::sync::atomic::Ordering;

use numpy::PyUntypedArray;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use rogue_gym_pool::BatchOutput;

use super::PyPool;
use crate::columns::{column_layout, raw_bytes, write_columns, write_final};
use crate::gil::lock_gil_free;

/// The joined extra info of a call: `(rows, data, size, ends)`. `rows`: the rows (env ids
/// for whole-batch calls) of the envs that wrote some, or `None` when every row did; `data`:
/// their bytes, one after the other; `size`: the length of each when all have the same length
/// and the same first `extras_head` bytes (one typed layout), else 0; `ends`: where each one's
/// bytes end in `data` (empty when `size` is not 0).
pub(super) type Joined<'py> = (Option<Vec<usize>>, Bound<'py, PyBytes>, usize, Vec<usize>);

/// A whole-batch call's result: `(slot, summary, extras)`.
pub(super) type SyncResult<'py> = (usize, usize, Option<Joined<'py>>);

/// Join `(row, bytes)` extras of a call with `rows` rows (see [`Joined`]); `None` when there
/// are none.
pub(super) fn join_extras<'py>(
    py: Python<'py>,
    extras: &[(usize, Vec<u8>)],
    rows: usize,
    head: usize,
) -> PyResult<Option<Joined<'py>>> {
    if extras.is_empty() {
        return Ok(None);
    }
    let every = extras.len() == rows && extras.iter().enumerate().all(|(i, (r, _))| *r == i);
    let which = (!every).then(|| extras.iter().map(|(r, _)| *r).collect());
    let first = &extras[0].1;
    let size = if first.len() >= head
        && extras
            .iter()
            .all(|(_, e)| e.len() == first.len() && e[..head] == first[..head])
    {
        first.len()
    } else {
        0
    };
    let total = extras.iter().map(|(_, e)| e.len()).sum();
    let data = PyBytes::new_with(py, total, |buf| {
        let mut at = 0;
        for (_, e) in extras {
            buf[at..at + e.len()].copy_from_slice(e);
            at += e.len();
        }
        Ok(())
    })?;
    let ends = if size > 0 {
        Vec::new()
    } else {
        extras
            .iter()
            .scan(0, |at, (_, e)| {
                *at += e.len();
                Some(*at)
            })
            .collect()
    };
    Ok(Some((which, data, size, ends)))
}

impl PyPool {
    /// Decode `out` into column buffer `buffer` (rows at their env ids, or with `at_row` at
    /// their row); the `SUMMARY_*` bits.
    pub(super) fn decode_into(
        &self,
        out: &BatchOutput,
        buffer: usize,
        at_row: bool,
    ) -> PyResult<usize> {
        let cols = self
            .columns
            .lock()
            .map_err(|_| PyRuntimeError::new_err("the pool lock is poisoned"))?;
        let &(_, ptr) = cols.get(buffer).ok_or_else(|| {
            PyRuntimeError::new_err(
                "results need bind_columns() with one buffer per slot and one for recv",
            )
        })?;
        // SAFETY: the buffer is kept alive by `cols` and was checked (size, alignment,
        // writeable) by `bind_columns`; we hold the GIL, so Python cannot touch it meanwhile.
        Ok(unsafe { write_columns(out, self.num_envs, self.n_info, ptr as *mut u8, at_row) })
    }

    /// Column buffers bound (the last one is `recv`'s).
    pub(super) fn columns_bound(&self) -> PyResult<usize> {
        Ok(self
            .columns
            .lock()
            .map_err(|_| PyRuntimeError::new_err("the pool lock is poisoned"))?
            .len())
    }

    /// The result of the whole-batch call that wrote `slot`: its values decoded into the
    /// slot's column buffer, its final observations into `final_out` (SAME_STEP), its extras.
    pub(super) fn sync_result<'py>(
        &self,
        py: Python<'py>,
        slot: usize,
        final_out: Option<&Bound<'_, PyUntypedArray>>,
    ) -> PyResult<SyncResult<'py>> {
        let fin = final_out
            .map(|f| {
                raw_bytes(
                    f,
                    "final observation buffer",
                    self.num_envs * self.obs_bytes,
                )
            })
            .transpose()?;
        let mut out = lock_gil_free(py, &self.out)?;
        if let Some(f) = fin {
            // SAFETY: the array is alive for this call and not otherwise borrowed by us.
            write_final(&out, self.obs_bytes, unsafe { f.slice() });
        }
        let summary = self.decode_into(&out, slot, false)?;
        let extras = std::mem::take(&mut out.extras);
        drop(out);
        let head = self.extras_head.load(Ordering::Relaxed);
        Ok((
            slot,
            summary,
            join_extras(py, &extras, self.num_envs, head)?,
        ))
    }
}

#[pymethods]
impl PyPool {
    /// The layout of a column buffer for `bind_columns`: `(list of (name, dtype, byte offset,
    /// rows), total bytes)`. Each column is `rows x num_envs`, C-contiguous.
    fn column_layout(&self) -> (Vec<(&'static str, &'static str, usize, usize)>, usize) {
        column_layout(self.num_envs, self.n_info)
    }

    /// Bind the column buffers every call's result is decoded into: one per shared batch
    /// slot, then one for `recv` (writable, C-contiguous, 8-aligned uint8 arrays of
    /// `column_layout()[1]` bytes). `extras_head`: the leading bytes extra infos of one
    /// layout share (a result reports one size when all share them).
    fn bind_columns(
        &self,
        buffers: Vec<Bound<'_, PyUntypedArray>>,
        extras_head: usize,
    ) -> PyResult<()> {
        let (_, total) = column_layout(self.num_envs, self.n_info);
        let mut v = Vec::with_capacity(buffers.len());
        for b in &buffers {
            let raw = raw_bytes(b, "column buffer", total)?;
            if !(raw.0 as usize).is_multiple_of(8) {
                return Err(PyValueError::new_err(
                    "column buffers must be 8-byte aligned",
                ));
            }
            v.push((b.clone().into_any().unbind(), raw.0 as usize));
        }
        *self
            .columns
            .lock()
            .map_err(|_| PyRuntimeError::new_err("the pool lock is poisoned"))? = v;
        self.extras_head.store(extras_head, Ordering::Relaxed);
        Ok(())
    }
}
