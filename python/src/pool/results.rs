//! What the results of every call share: per-env values are columns (a whole-batch call's in
//! its batch slot, where the workers wrote them, read in place: `sync_api.rs`; a `recv`'s
//! written here into the `recv` column buffer), a summary (`SUMMARY_*` bits), and the extra
//! info (hosted envs' infos) joined here, all from the same native call.

use numpy::PyUntypedArray;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use rogue_gym_pool::{EXTRA_HEAD, Received, SlotExtras};

use super::PyPool;
use crate::columns::{SUMMARY_FINAL, SUMMARY_RESTARTED, raw_bytes, recv_layout};

/// The joined extra info of a call: `(rows, data, size, ends)`. `rows`: the rows (env ids
/// for whole-batch calls) of the envs that wrote some, or `None` when every row did; `data`:
/// their bytes, one after the other (`None`: every env wrote `size` bytes into its room of the
/// slot's extra area, to be read there); `size`: the length of each when all have the same
/// length and the same first [`EXTRA_HEAD`] bytes (one typed layout), else 0; `ends`: where
/// each one's bytes end in `data` (empty when `size` is not 0).
pub(super) type Joined<'py> = (
    Option<Vec<usize>>,
    Option<Bound<'py, PyBytes>>,
    usize,
    Vec<usize>,
);

/// The `SUMMARY_*` bits of a call's result (`finals`: its final observations are read, as a
/// whole-batch call's are; a `recv` hands over none).
pub(super) fn summary(got: &Received, finals: bool) -> usize {
    let mut bits = 0;
    if got.restarted {
        bits |= SUMMARY_RESTARTED;
    }
    if finals && got.final_obs {
        bits |= SUMMARY_FINAL;
    }
    bits
}

/// A result's extra info of `rows` rows, joined (see [`Joined`]); `None` when there is none.
pub(super) fn joined<'py>(
    py: Python<'py>,
    extras: &SlotExtras,
    rows: usize,
) -> PyResult<Option<Joined<'py>>> {
    match extras {
        SlotExtras::None => Ok(None),
        &SlotExtras::Uniform(size) => Ok(Some((None, None, size, Vec::new()))),
        SlotExtras::Rows(x) => join_extras(py, x, rows),
    }
}

/// Join `(row, bytes)` extras of a call with `rows` rows (see [`Joined`]); `None` when there
/// are none.
fn join_extras<'py>(
    py: Python<'py>,
    extras: &[(usize, Vec<u8>)],
    rows: usize,
) -> PyResult<Option<Joined<'py>>> {
    let head = EXTRA_HEAD;
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
    Ok(Some((which, Some(data), size, ends)))
}

impl PyPool {
    /// Write a `recv`'s gathered records into the bound `recv` column buffer.
    pub(super) fn write_recv_columns(&self, got: &Received) -> PyResult<()> {
        let cols = crate::gil::lock_any(&self.columns);
        let &(_, ptr) = cols.as_ref().ok_or_else(|| {
            PyRuntimeError::new_err("recv needs bind_recv_columns() with its column buffer")
        })?;
        // SAFETY: the buffer is kept alive by `cols` and was checked (size, alignment,
        // writeable) by `bind_recv_columns`; we hold the GIL, so Python cannot touch it
        // meanwhile.
        let columns = unsafe { recv_layout(self.num_envs, self.n_info).rows(ptr as *mut u8) };
        got.write_columns(&columns);
        Ok(())
    }
}

#[pymethods]
impl PyPool {
    /// The layout of the columns of a batch slot, and of the `recv` column buffer:
    /// `(list of (name, dtype, byte offset, rows, bytes from row to row), total bytes)`.
    /// Each column is `rows` rows of `num_envs` entries.
    fn column_layout(&self) -> (Vec<rogue_gym_pool::ColumnView>, usize) {
        recv_layout(self.num_envs, self.n_info).column_views()
    }

    /// Bind the column buffer every `recv`'s rows are written into (a writable, C-contiguous,
    /// 8-aligned uint8 array of `column_layout()[1]` bytes).
    fn bind_recv_columns(&self, buffer: Bound<'_, PyUntypedArray>) -> PyResult<()> {
        let (_, total) = recv_layout(self.num_envs, self.n_info).column_views();
        let raw = raw_bytes(&buffer, "column buffer", total)?;
        if !(raw as usize).is_multiple_of(8) {
            return Err(PyValueError::new_err(
                "the column buffer must be 8-byte aligned",
            ));
        }
        *crate::gil::lock_any(&self.columns) = Some((buffer.into_any().unbind(), raw as usize));
        Ok(())
    }
}
