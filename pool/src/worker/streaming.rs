//! Streaming stores: copying an env's observation into its row of shared memory without
//! pulling the row into the cache first.
//!
//! A plain store to a line not in the cache first reads the line (read for ownership), then
//! keeps it in the cache, where it pushes out what the caller and the envs use. A batch whose
//! observations are larger than the cache (the native game: 8.7 KB an env, 35 MB for 4,096
//! envs) pays both on every step: the worker moves each byte twice, and the caller's next
//! turn starts with a cold cache. Non-temporal stores write whole lines to memory directly.
//!
//! They are weakly ordered: [`fence`] must run after the last of them and before the answer
//! that publishes the rows (iceoryx2's release store does not order them on x86-64).
//!
//! A batch that fits the cache is better written plainly: its lines are still there from the
//! last time its slot was written, so the stores cost no memory traffic, and the caller reads
//! it from the cache. [`wanted`] draws the line where the observations of all the batch slots
//! take more than [`CACHE_SHARE`] of the last-level cache: below it streaming measured slower,
//! above it faster (`benchmarks/streaming.py`; the figures in docs/performance.md, "Memory
//! traffic").

/// Stream the rows when the observations of all the batch slots take more than this share of
/// the last-level cache (as a divisor: a third).
pub(crate) const CACHE_SHARE: usize = 3;

/// The last-level cache assumed where the system does not say (`/sys` not mounted).
const DEFAULT_CACHE_BYTES: usize = 32 << 20;

/// Whether to stream the rows when the observations of all the batch slots take
/// `slots_obs_bytes`: `setting` when given (`PoolConfig::streaming_stores`), else whether
/// they take more than [`CACHE_SHARE`] of the last-level cache.
pub(crate) fn wanted(setting: Option<bool>, slots_obs_bytes: usize) -> bool {
    setting.unwrap_or_else(|| {
        slots_obs_bytes > last_level_cache().unwrap_or(DEFAULT_CACHE_BYTES) / CACHE_SHARE
    })
}

/// The size of CPU 0's largest cache, from `/sys/devices/system/cpu/cpu0/cache`.
fn last_level_cache() -> Option<usize> {
    let dir = std::fs::read_dir("/sys/devices/system/cpu/cpu0/cache").ok()?;
    dir.filter_map(|e| {
        let path = e.ok()?.path();
        let level: u32 = std::fs::read_to_string(path.join("level"))
            .ok()?
            .trim()
            .parse()
            .ok()?;
        Some((
            level,
            cache_bytes(&std::fs::read_to_string(path.join("size")).ok()?)?,
        ))
    })
    .max()
    .map(|(_, bytes)| bytes)
}

/// Bytes of a sysfs cache size (`"32768K"`, `"1M"`, `"512"`).
fn cache_bytes(text: &str) -> Option<usize> {
    let t = text.trim();
    let (digits, unit) = match t.char_indices().find(|(_, c)| !c.is_ascii_digit()) {
        Some((i, _)) => t.split_at(i),
        None => (t, ""),
    };
    let n: usize = digits.parse().ok()?;
    let scale = match unit {
        "" => 1,
        "K" => 1 << 10,
        "M" => 1 << 20,
        "G" => 1 << 30,
        _ => return None,
    };
    n.checked_mul(scale)
}

/// Copy `src` into `dst` (the same length) with non-temporal stores where the target has
/// them (x86-64: SSE2's `movntdq`, 16 bytes a store; the unaligned ends with plain stores);
/// elsewhere a plain copy. Call [`fence`] before publishing `dst`.
#[inline]
pub(crate) fn copy(dst: &mut [u8], src: &[u8]) {
    let n = dst.len().min(src.len());
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128i, _mm_loadu_si128, _mm_stream_si128};
        let head = dst.as_ptr().align_offset(16).min(n);
        let body = (n - head) / 16 * 16;
        dst[..head].copy_from_slice(&src[..head]);
        let mut i = head;
        while i < head + body {
            // SAFETY: `i + 16 <= head + body <= n`, inside both slices; `dst + i` is 16-byte
            // aligned (`head` aligns it, `i - head` is a multiple of 16); SSE2 is part of the
            // x86-64 baseline.
            unsafe {
                let v = _mm_loadu_si128(src.as_ptr().add(i).cast::<__m128i>());
                _mm_stream_si128(dst.as_mut_ptr().add(i).cast::<__m128i>(), v);
            }
            i += 16;
        }
        dst[i..n].copy_from_slice(&src[i..n]);
    }
    #[cfg(not(target_arch = "x86_64"))]
    dst[..n].copy_from_slice(&src[..n]);
}

/// Order every streaming store of this thread before the stores that follow (x86-64:
/// `sfence`; elsewhere nothing, as [`copy`] stores plainly there).
#[inline]
pub(crate) fn fence() {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE is part of the x86-64 baseline.
    unsafe {
        std::arch::x86_64::_mm_sfence();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_sysfs_cache_sizes() {
        assert_eq!(cache_bytes("32768K\n"), Some(32 << 20));
        assert_eq!(cache_bytes("1M"), Some(1 << 20));
        assert_eq!(cache_bytes("512"), Some(512));
        assert_eq!(cache_bytes("12Q"), None);
        assert_eq!(cache_bytes(""), None);
    }

    #[test]
    fn a_setting_wins_and_auto_streams_only_what_outgrows_the_cache() {
        assert!(wanted(Some(true), 0));
        assert!(!wanted(Some(false), usize::MAX));
        assert!(!wanted(None, 64 << 10));
        assert!(wanted(None, usize::MAX));
    }

    #[test]
    fn copies_every_byte_at_every_alignment_and_length() {
        let src: Vec<u8> = (0..200u32).map(|i| (i * 7 + 3) as u8).collect();
        let mut buf = vec![0u8; 256];
        for offset in 0..17 {
            for len in [0, 1, 15, 16, 17, 31, 32, 33, 100, 183] {
                buf.fill(0xAA);
                copy(&mut buf[offset..offset + len], &src[..len]);
                fence();
                assert_eq!(
                    &buf[offset..offset + len],
                    &src[..len],
                    "offset {offset} len {len}"
                );
                assert!(
                    buf[..offset].iter().all(|&b| b == 0xAA),
                    "before, offset {offset}"
                );
                assert!(
                    buf[offset + len..].iter().all(|&b| b == 0xAA),
                    "after, len {len}"
                );
            }
        }
    }
}
