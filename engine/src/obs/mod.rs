//! Observation specs and encoders. The game keeps a per-cell symbol screen up to date; the
//! encoders write it (plus optional status planes and the visited-history plane) straight into a
//! caller-provided buffer, so a pool worker can encode into shared memory with no copy.
//!
//! Layouts (C = channels, H = height, W = width, k = popcount of the status flags,
//! hist = 1 if `history`):
//!
//! | encoding | shape | content |
//! |---|---|---|
//! | `symbol_onehot` | (symbols + k + hist, H, W) | 1 (u8) / 1.0 (f32) where the cell has that symbol |
//! | `symbol_index` | (H, W), or (1 + k + hist, H, W) when status or history is set | symbol index |
//! | `gray` | (1 + k + hist, H, W) | f32: index / symbols; u8: index * 255 / symbols |
//! | `ascii` | (H, W), or (1 + k + hist, H, W) when status or history is set | screen bytes |
//! | `status` | (n,) with n = k, or 9 when the flags are empty | status values in flag order |
//!
//! Status planes are constant planes, in flag order, holding the raw value (u8: saturated to
//! 0..=255) or, with `normalize_status`, the value normalised into [0, 1] (u8: scaled to 0..=255;
//! see [`Status::normalized`]). The history plane is 1 on every cell the player stood on in
//! this floor. Rows 0 and H-1 (message and status lines) are always symbol 0 (blank).

mod encode;
mod spec;
mod status;

pub(crate) use encode::{ObsSource, shape, write};
pub use spec::{Dtype, Encoding, ObsBufMut, ObsError, ObsSpec, StatusFlags};
pub use status::Status;
