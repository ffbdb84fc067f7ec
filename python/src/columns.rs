//! The `recv` column buffer (the columns of a batch slot, rows in receive order), the raw data
//! pointer of the numpy array behind it, and the summary bits of a result. Whole-batch calls
//! need no column buffer: their workers write every row in place in a batch slot.

use numpy::npyffi::flags::NPY_ARRAY_WRITEABLE;
use numpy::{PyArrayDescrMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rogue_gym_pool::SlotLayout;

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
