//! The `recv` column buffer (the columns of a batch slot, rows in receive order) and the raw
//! data pointer of the numpy array behind it. Whole-batch calls need
//! neither: their workers write every row in place in a batch slot.

use numpy::npyffi::flags::NPY_ARRAY_WRITEABLE;
use numpy::{PyArrayDescrMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rogue_gym_pool::{
    BatchOutput, EnvRecord, FLAG_FINAL_OBS, FLAG_RESTARTED, FLAG_TERMINATED, FLAG_TRUNCATED,
    SlotLayout,
};

/// The data pointer of a writable, C-contiguous numpy array, checked against an expected
/// size in bytes.
pub(crate) fn raw_bytes(
    arr: &Bound<'_, PyUntypedArray>,
    what: &str,
    expected: usize,
) -> PyResult<*mut u8> {
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
    Ok(data)
}

/// The layout of a `recv` column buffer: the columns of a batch slot alone (the same names,
/// dtypes and order: [`rogue_gym_pool::COLUMNS`]), rows in receive order.
pub(crate) fn recv_layout(num_envs: usize, n_info: usize) -> SlotLayout {
    SlotLayout {
        num_envs,
        obs_bytes: 0,
        n_info,
        final_obs: false,
        extra_bytes: 0,
    }
}

/// Summary bit of a call's result: some env's worker was restarted.
pub(crate) const SUMMARY_RESTARTED: usize = 1;
/// Summary bit of a call's result: some env has a final observation (SAME_STEP).
pub(crate) const SUMMARY_FINAL: usize = 1 << 1;

/// Write the rows of `out` into a `recv` column buffer ([`recv_layout`] of `n` envs), row `r`
/// at index `r`; returns the `SUMMARY_*` bits.
///
/// # Safety
/// `base` must point to a live, 64-aligned, writable buffer of the layout's size.
pub(crate) unsafe fn write_rows(
    out: &BatchOutput,
    n: usize,
    n_info: usize,
    base: *mut u8,
) -> usize {
    // SAFETY: the caller's promise.
    let w = unsafe { recv_layout(n, n_info).writer(base) };
    let mut summary = 0;
    for r in 0..out.env_ids.len().min(n) {
        let mut flags = 0;
        if out.terminated[r] {
            flags |= FLAG_TERMINATED;
        }
        if out.truncated[r] {
            flags |= FLAG_TRUNCATED;
        }
        if out.restarted[r] {
            flags |= FLAG_RESTARTED;
            summary |= SUMMARY_RESTARTED;
        }
        if out.has_final_obs[r] {
            flags |= FLAG_FINAL_OBS;
            summary |= SUMMARY_FINAL;
        }
        let mut rec = EnvRecord {
            reward: out.reward[r],
            flags,
            episode_length: out.episode_length[r],
            episode_return: out.episode_return[r],
            episode: out.episode[r],
            seed: out.seed[r],
            ..Default::default()
        };
        rec.info[..n_info].copy_from_slice(&out.info[r * n_info..(r + 1) * n_info]);
        w.record(r, &rec);
    }
    summary
}
