//! Writing a call's per-env values for Python: the column buffers every call's results are
//! decoded into (one form for steps, resets, partial resets and `recv`), the final
//! observations; plus the raw byte view of a numpy array that the pool writes without the GIL.

use numpy::npyffi::flags::NPY_ARRAY_WRITEABLE;
use numpy::{PyArrayDescrMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rogue_gym_pool::BatchOutput;

/// A raw mutable byte buffer handed to code running without the GIL.
pub(crate) struct RawBuf(pub(crate) *mut u8, pub(crate) usize);
// SAFETY: the buffer belongs to a numpy array the caller keeps alive for the whole call; the
// pointer is only dereferenced inside that call.
unsafe impl Send for RawBuf {}

impl RawBuf {
    /// # Safety
    /// The array behind the pointer must stay alive and unaliased while the slice is used.
    pub(crate) unsafe fn slice<'a>(&self) -> &'a mut [u8] {
        if self.1 == 0 {
            return &mut [];
        }
        unsafe { std::slice::from_raw_parts_mut(self.0, self.1) }
    }
}

/// The writable, C-contiguous bytes of a numpy array, checked against an expected size.
pub(crate) fn raw_bytes(
    arr: &Bound<'_, PyUntypedArray>,
    what: &str,
    expected: usize,
) -> PyResult<RawBuf> {
    if !arr.is_c_contiguous() {
        return Err(PyValueError::new_err(format!(
            "{what} must be C-contiguous"
        )));
    }
    let ptr = arr.as_array_ptr();
    // SAFETY: `ptr` is a live array object (we hold a reference to it).
    let (data, flags) = unsafe { ((*ptr).fields.data as *mut u8, (*ptr).fields.flags) };
    if flags & NPY_ARRAY_WRITEABLE == 0 {
        return Err(PyValueError::new_err(format!("{what} must be writeable")));
    }
    let nbytes = arr.len() * arr.dtype().itemsize();
    if nbytes != expected {
        return Err(PyValueError::new_err(format!(
            "{what} has {nbytes} bytes (shape {:?}, dtype {}), expected {expected}",
            arr.shape(),
            arr.dtype()
        )));
    }
    Ok(RawBuf(data, nbytes))
}

/// Copy the valid final observations of `out` to their env rows of `fin`.
pub(crate) fn write_final(out: &BatchOutput, obs_bytes: usize, fin: &mut [u8]) {
    if out.final_obs.is_empty() {
        return;
    }
    for (r, &env) in out.env_ids.iter().enumerate() {
        if out.has_final_obs[r] {
            fin[env * obs_bytes..(env + 1) * obs_bytes]
                .copy_from_slice(&out.final_obs[r * obs_bytes..(r + 1) * obs_bytes]);
        }
    }
}

/// The column layout of a `bind_columns` buffer: `(name, numpy dtype, byte offset, rows)`; each
/// column is `rows x num_envs` C-contiguous. Eight-byte columns come first (8-aligned).
pub(crate) fn column_layout(
    n: usize,
    n_info: usize,
) -> (Vec<(&'static str, &'static str, usize, usize)>, usize) {
    let cols: [(&'static str, &'static str, usize, usize); 11] = [
        ("reward", "float64", 8, 1),
        ("seed", "uint64", 8, 1),
        ("episode_index", "int64", 8, 1),
        ("episode_return", "float64", 8, 1),
        ("episode_length", "int64", 8, 1),
        ("info_int", "int64", 8, n_info),
        ("terminated", "bool", 1, 1),
        ("truncated", "bool", 1, 1),
        ("restarted", "bool", 1, 1),
        ("has_final_obs", "bool", 1, 1),
        ("info_bool", "bool", 1, n_info),
    ];
    let mut off = 0;
    let mut v = Vec::with_capacity(cols.len());
    for (name, dt, size, rows) in cols {
        v.push((name, dt, off, rows));
        off += size * rows * n;
    }
    (v, off)
}

/// Summary bit of a call's result: some env's worker was restarted.
pub(crate) const SUMMARY_RESTARTED: usize = 1;
/// Summary bit of a call's result: some env has a final observation (SAME_STEP).
pub(crate) const SUMMARY_FINAL: usize = 1 << 1;

/// Write the rows of `out` into a column buffer of `n` entries per column (see
/// [`column_layout`]), each at its env's index or, with `at_row`, at its row's; returns the
/// `SUMMARY_*` bits.
///
/// # Safety
/// `base` must point to a live, 8-aligned, writable buffer of the layout's size.
pub(crate) unsafe fn write_columns(
    out: &BatchOutput,
    n: usize,
    n_info: usize,
    base: *mut u8,
    at_row: bool,
) -> usize {
    let w = |col: usize| unsafe { base.cast::<u64>().add(col * n) };
    let b8 = 8 * n * (5 + n_info);
    let b = |col: usize| unsafe { base.add(b8 + col * n) };
    let mut summary = 0;
    for (r, &env) in out.env_ids.iter().enumerate() {
        let i = if at_row { r } else { env };
        if i >= n {
            continue;
        }
        unsafe {
            *w(0).add(i) = out.reward[r].to_bits();
            *w(1).add(i) = out.seed[r];
            *w(2).add(i) = out.episode[r];
            *w(3).add(i) = out.episode_return[r].to_bits();
            *w(4).add(i) = u64::from(out.episode_length[r]);
            for k in 0..n_info {
                let v = out.info[r * n_info + k];
                *w(5 + k).add(i) = (v as i64) as u64;
                *b(4 + k).add(i) = u8::from(v != 0.0);
            }
            *b(0).add(i) = u8::from(out.terminated[r]);
            *b(1).add(i) = u8::from(out.truncated[r]);
            *b(2).add(i) = u8::from(out.restarted[r]);
            *b(3).add(i) = u8::from(out.has_final_obs[r]);
        }
        if out.restarted[r] {
            summary |= SUMMARY_RESTARTED;
        }
        if out.has_final_obs[r] {
            summary |= SUMMARY_FINAL;
        }
    }
    summary
}
