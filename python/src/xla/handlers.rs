//! The two `extern "C"` FFI handlers and the typed views of their buffers. Neither panics
//! across the boundary: every failure becomes an XLA error whose message says what was wrong.
//!
//! - `rogue_gym_send(handle, action[, env_id]) -> handle`
//! - `rogue_gym_recv(handle) -> (handle, obs, reward, terminated, truncated, env_id,
//!   elapsed_step, restarted[, info])`, `info` being `(rows, n_info)` when the env has typed
//!   info values.

use std::ffi::{c_int, c_void};
use std::panic::{AssertUnwindSafe, catch_unwind};

use rogue_gym_pool::EnvRecord;

use super::ffi::{self, Buffer, CallFrame, DataType, Values};

/// An FFI handler's C signature.
pub(crate) type Handler = unsafe extern "C" fn(*mut CallFrame) -> *mut c_void;

/// One argument or result buffer.
pub(crate) struct Buf {
    dtype: DataType,
    data: *mut u8,
    dims: Vec<usize>,
}

impl Buf {
    /// Elements in all.
    fn len(&self) -> usize {
        self.dims.iter().product()
    }

    /// Rows (the leading dimension; 1 for a scalar).
    pub(crate) fn rows(&self) -> usize {
        self.dims.first().copied().unwrap_or(1)
    }

    /// The raw bytes.
    pub(crate) fn bytes(&self) -> &[u8] {
        // SAFETY: XLA hands a buffer of `len` elements of `dtype`, alive for the call.
        unsafe { std::slice::from_raw_parts(self.data, self.len() * self.dtype.size()) }
    }

    /// The raw bytes, writable (a result buffer).
    pub(crate) fn bytes_mut(&mut self) -> &mut [u8] {
        // SAFETY: as `bytes`; result buffers are the handler's to write.
        unsafe { std::slice::from_raw_parts_mut(self.data, self.len() * self.dtype.size()) }
    }

    /// The values of an integer buffer, as `i64`.
    pub(crate) fn integers(&self, what: &str) -> Result<Vec<i64>, String> {
        let b = self.bytes();
        macro_rules! read {
            ($t:ty) => {
                b.chunks_exact(std::mem::size_of::<$t>())
                    .map(|c| <$t>::from_ne_bytes(c.try_into().unwrap_or_default()) as i64)
                    .collect()
            };
        }
        Ok(match self.dtype {
            DataType::S8 => read!(i8),
            DataType::S16 => read!(i16),
            DataType::S32 => read!(i32),
            DataType::S64 => read!(i64),
            DataType::U8 => read!(u8),
            DataType::U16 => read!(u16),
            DataType::U32 => read!(u32),
            DataType::U64 => read!(u64),
            other => {
                return Err(format!(
                    "{what} must be an integer array (this env's actions are indices), got {other:?}"
                ));
            }
        })
    }

    /// The values of an integer buffer as env ids, each checked to be below `num_envs`.
    pub(crate) fn indices(&self, what: &str, num_envs: usize) -> Result<Vec<usize>, String> {
        self.integers(what)?
            .into_iter()
            .map(|i| {
                usize::try_from(i)
                    .ok()
                    .filter(|&e| e < num_envs)
                    .ok_or_else(|| {
                        format!(
                            "{what} {i} is out of range: env ids are 0 to {}",
                            num_envs - 1
                        )
                    })
            })
            .collect()
    }

    /// Write `values` (one per element, in order) converted to the buffer's type: one of
    /// those `rogue_gym.xla` declares the outputs with (float32, int32, bool), or their
    /// 64-bit forms. The type is matched once, not per element.
    fn put(&mut self, values: impl Iterator<Item = f64>) -> Result<(), String> {
        let n = self.len();
        macro_rules! fill {
            ($t:ty, $conv:expr) => {{
                // SAFETY: a result buffer of `n` elements of this type, alive for the call.
                let dst = unsafe { std::slice::from_raw_parts_mut(self.data.cast::<$t>(), n) };
                for (d, v) in dst.iter_mut().zip(values) {
                    *d = $conv(v);
                }
            }};
        }
        match self.dtype {
            DataType::F32 => fill!(f32, |v: f64| v as f32),
            DataType::F64 => fill!(f64, |v: f64| v),
            DataType::S32 => fill!(i32, |v: f64| v as i32),
            DataType::S64 => fill!(i64, |v: f64| v as i64),
            DataType::Pred | DataType::U8 => fill!(u8, |v: f64| u8::from(v != 0.0)),
            other => {
                return Err(format!(
                    "recv(): an output of type {other:?} is not written here"
                ));
            }
        }
        Ok(())
    }
}

/// The results of a `recv`, in order.
pub(crate) struct Outputs<'a> {
    pub(crate) obs: Buf,
    rest: &'a mut [Buf],
}

impl Outputs<'_> {
    /// Write the rows of envs `env_ids`, `records` (in order), into the outputs after `obs`.
    pub(crate) fn write(
        &mut self,
        env_ids: &[usize],
        records: &[EnvRecord],
        n_info: usize,
    ) -> Result<(), String> {
        let [
            reward,
            terminated,
            truncated,
            env_id,
            elapsed,
            restarted,
            info @ ..,
        ] = self.rest
        else {
            return Err("recv() has too few results".into());
        };
        let bool_of = |b: bool| f64::from(u8::from(b));
        reward.put(records.iter().map(|r| r.reward))?;
        terminated.put(records.iter().map(|r| bool_of(r.terminated())))?;
        truncated.put(records.iter().map(|r| bool_of(r.truncated())))?;
        env_id.put(env_ids.iter().map(|&e| e as f64))?;
        elapsed.put(records.iter().map(|r| f64::from(r.episode_length)))?;
        restarted.put(records.iter().map(|r| bool_of(r.restarted())))?;
        if let [info] = info
            && n_info > 0
        {
            info.put(
                records
                    .iter()
                    .flat_map(|r| r.info[..n_info].iter().copied()),
            )?;
        }
        Ok(())
    }
}

/// The buffers of `values` (arguments or results).
///
/// # Safety
/// `values` must be a call frame's arguments or results.
unsafe fn buffers(values: &Values, what: &str) -> Result<Vec<Buf>, String> {
    let n = usize::try_from(values.size).unwrap_or(0);
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        // SAFETY: `types` and `values` have `size` entries.
        let (ty, ptr) = unsafe { (*values.types.add(i), *values.values.add(i)) };
        if ty != ffi::TYPE_BUFFER {
            return Err(format!("{what} {i} is not a buffer"));
        }
        // SAFETY: a buffer entry points to an `XLA_FFI_Buffer`.
        let b = unsafe { &*(ptr as *const Buffer) };
        let dtype = DataType::from_code(b.dtype).ok_or_else(|| {
            format!(
                "{what} {i} has an element type (code {}) not taken here",
                b.dtype
            )
        })?;
        let rank = usize::try_from(b.rank).unwrap_or(0);
        // SAFETY: `dims` has `rank` entries.
        let dims = (0..rank)
            .map(|d| usize::try_from(unsafe { *b.dims.add(d) }).unwrap_or(0))
            .collect();
        out.push(Buf {
            dtype,
            data: b.data as *mut u8,
            dims,
        });
    }
    Ok(out)
}

/// Answer the registration's metadata query (API version 0.1, no traits), if this call is
/// one.
///
/// # Safety
/// `frame` must be a valid call frame.
unsafe fn metadata_query(frame: &CallFrame) -> bool {
    let ext = frame.extension_start;
    // SAFETY: a non-null extension chain of valid extensions.
    if ext.is_null() || unsafe { (*ext).kind } != ffi::EXTENSION_METADATA {
        return false;
    }
    // SAFETY: an extension of kind Metadata is an `XLA_FFI_Metadata_Extension`.
    let meta = unsafe { (*(ext as *const ffi::MetadataExtension)).metadata };
    if let Some(m) = unsafe { meta.as_mut() } {
        m.api_version = ffi::ApiVersion {
            struct_size: std::mem::size_of::<ffi::ApiVersion>(),
            extension_start: std::ptr::null_mut(),
            major: 0,
            minor: 1,
        };
        m.traits = 0;
    }
    true
}

/// Run `body` for an execute-stage call of `frame`, turning errors and panics into XLA errors.
///
/// # Safety
/// `frame` must be the call frame XLA passed.
unsafe fn serve(
    frame: *mut CallFrame,
    body: impl FnOnce(i32, Vec<Buf>, Vec<Buf>) -> Result<(), String>,
) -> *mut c_void {
    // SAFETY: XLA passes a valid call frame.
    let Some(frame) = (unsafe { frame.as_ref() }) else {
        return std::ptr::null_mut();
    };
    // SAFETY: as above.
    if unsafe { metadata_query(frame) } || frame.stage != ffi::STAGE_EXECUTE {
        return std::ptr::null_mut();
    }
    let api = frame.api;
    let fail = |code: c_int, msg: &str| unsafe { ffi::error(api, code, msg) };
    // SAFETY: the frame's arguments and results.
    let parsed = unsafe { buffers(&frame.args, "argument") }
        .and_then(|a| Ok((a, unsafe { buffers(&frame.rets, "result") }?)));
    let (args, rets) = match parsed {
        Ok(v) => v,
        Err(e) => return fail(ffi::INVALID_ARGUMENT, &format!("rogue_gym xla: {e}")),
    };
    let key = match args.first().map(|h| h.integers("handle")) {
        Some(Ok(v)) if !v.is_empty() => v[0] as i32,
        _ => {
            return fail(
                ffi::INVALID_ARGUMENT,
                "rogue_gym xla: the first argument must be the handle that xla() returned",
            );
        }
    };
    let run = catch_unwind(AssertUnwindSafe(|| body(key, args, rets)));
    match run {
        Ok(Ok(())) => std::ptr::null_mut(),
        Ok(Err(e)) => fail(ffi::FAILED_PRECONDITION, &format!("rogue_gym xla: {e}")),
        Err(_) => fail(
            ffi::INTERNAL,
            "rogue_gym xla: the handler panicked (a bug: please report it)",
        ),
    }
}

fn target(key: i32) -> Result<std::sync::Arc<super::XlaTarget>, String> {
    super::lookup(key).ok_or_else(|| {
        "the pool of this xla() handle is closed (or the handle is not one xla() returned): make a new pool and call xla() again".into()
    })
}

/// Copy the handle argument into the handle result.
fn pass_handle(args: &[Buf], rets: &mut [Buf]) -> Result<(), String> {
    let (Some(h), Some(out)) = (args.first(), rets.first_mut()) else {
        return Err("a handle result is missing".into());
    };
    let src = h.bytes();
    let dst = out.bytes_mut();
    if src.len() != dst.len() {
        return Err("the handle result does not match the handle".into());
    }
    dst.copy_from_slice(src);
    Ok(())
}

/// `rogue_gym_send(handle, action[, env_id]) -> handle`.
///
/// # Safety
/// Called by XLA with a valid call frame.
pub(crate) unsafe extern "C" fn rogue_gym_send(frame: *mut CallFrame) -> *mut c_void {
    // SAFETY: XLA's call frame.
    unsafe {
        serve(frame, |key, args, mut rets| {
            let t = target(key)?;
            let action = args.get(1).ok_or("send() needs an action argument")?;
            t.send(action, args.get(2))?;
            pass_handle(&args, &mut rets)
        })
    }
}

/// `rogue_gym_recv(handle) -> (handle, obs, reward, terminated, truncated, env_id,
/// elapsed_step, restarted[, info])`.
///
/// # Safety
/// Called by XLA with a valid call frame.
pub(crate) unsafe extern "C" fn rogue_gym_recv(frame: *mut CallFrame) -> *mut c_void {
    // SAFETY: XLA's call frame.
    unsafe {
        serve(frame, |key, args, mut rets| {
            let t = target(key)?;
            pass_handle(&args, &mut rets)?;
            let want = 8 + usize::from(t.n_info() > 0);
            if rets.len() != want {
                return Err(format!(
                    "recv() has {} results, expected {want}",
                    rets.len()
                ));
            }
            let rows = t.rows();
            if let Some(bad) = rets[1..].iter().find(|b| b.rows() != rows) {
                return Err(format!(
                    "recv() results must have {rows} rows (the batch), one has {}",
                    bad.rows()
                ));
            }
            let mut it = rets.into_iter().skip(1);
            let obs = it.next().ok_or("no observation result")?;
            let mut rest: Vec<Buf> = it.collect();
            let mut outs = Outputs {
                obs,
                rest: &mut rest,
            };
            t.recv(&mut outs)
        })
    }
}
