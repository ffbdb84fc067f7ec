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

use std::fmt;
use std::str::FromStr;

/// How the map is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Encoding {
    /// One channel per symbol (the paper's encoding).
    SymbolOnehot,
    /// The symbol index of each cell.
    SymbolIndex,
    /// One channel: symbol index / symbol count.
    Gray,
    /// The screen bytes.
    Ascii,
    /// Only the status values, no map.
    StatusVector,
}

impl FromStr for Encoding {
    type Err = ObsError;
    fn from_str(s: &str) -> Result<Self, ObsError> {
        Ok(match s {
            "symbol_onehot" => Encoding::SymbolOnehot,
            "symbol_index" => Encoding::SymbolIndex,
            "gray" => Encoding::Gray,
            "ascii" => Encoding::Ascii,
            "status" => Encoding::StatusVector,
            _ => {
                return Err(ObsError::UnknownName {
                    what: "encoding",
                    name: s.to_string(),
                });
            }
        })
    }
}

impl fmt::Display for Encoding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Encoding::SymbolOnehot => "symbol_onehot",
            Encoding::SymbolIndex => "symbol_index",
            Encoding::Gray => "gray",
            Encoding::Ascii => "ascii",
            Encoding::StatusVector => "status",
        })
    }
}

/// Element type of an observation buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Dtype {
    /// `u8`.
    U8,
    /// `f32`.
    F32,
}

impl FromStr for Dtype {
    type Err = ObsError;
    fn from_str(s: &str) -> Result<Self, ObsError> {
        match s {
            "u8" | "uint8" => Ok(Dtype::U8),
            "f32" | "float32" => Ok(Dtype::F32),
            _ => Err(ObsError::UnknownName {
                what: "dtype",
                name: s.to_string(),
            }),
        }
    }
}

impl fmt::Display for Dtype {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Dtype::U8 => "u8",
            Dtype::F32 => "f32",
        })
    }
}

/// The original's status flags (a u16 bit set). Bit order is plane order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct StatusFlags(pub u16);

impl StatusFlags {
    /// No status.
    pub const EMPTY: StatusFlags = StatusFlags(0);
    /// Dungeon level.
    pub const DUNGEON_LEVEL: StatusFlags = StatusFlags(1);
    /// Current HP.
    pub const HP_CURRENT: StatusFlags = StatusFlags(2);
    /// Max HP.
    pub const HP_MAX: StatusFlags = StatusFlags(4);
    /// Current strength.
    pub const STR_CURRENT: StatusFlags = StatusFlags(8);
    /// Max strength.
    pub const STR_MAX: StatusFlags = StatusFlags(16);
    /// Defence (armour).
    pub const DEFENSE: StatusFlags = StatusFlags(32);
    /// Player level.
    pub const PLAYER_LEVEL: StatusFlags = StatusFlags(64);
    /// Experience.
    pub const EXP: StatusFlags = StatusFlags(128);
    /// Hunger (0 normal, 1 hungry, 2 weak).
    pub const HUNGER: StatusFlags = StatusFlags(256);
    /// All 9.
    pub const FULL: StatusFlags = StatusFlags(511);

    /// Number of selected values (bits above the 9th are ignored).
    pub fn count(self) -> usize {
        (self.0 & 511).count_ones() as usize
    }

    /// Does it contain all bits of `other`?
    pub fn contains(self, other: StatusFlags) -> bool {
        self.0 & other.0 == other.0
    }
}

impl std::ops::BitOr for StatusFlags {
    type Output = StatusFlags;
    fn bitor(self, rhs: StatusFlags) -> StatusFlags {
        StatusFlags(self.0 | rhs.0)
    }
}

/// What to encode and how.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ObsSpec {
    /// Map encoding.
    pub encoding: Encoding,
    /// Element type.
    pub dtype: Dtype,
    /// Status planes (or values, for `StatusVector`) to append.
    pub status: StatusFlags,
    /// Normalise status values into [0, 1].
    pub normalize_status: bool,
    /// Append the visited-history plane (ignored by `StatusVector`).
    pub history: bool,
}

impl ObsSpec {
    /// The paper's: symbol one-hot, u8, no status, no history (17x16x32 on the paper config).
    pub fn paper() -> ObsSpec {
        ObsSpec {
            encoding: Encoding::SymbolOnehot,
            dtype: Dtype::U8,
            status: StatusFlags::EMPTY,
            normalize_status: false,
            history: false,
        }
    }
}

impl Default for ObsSpec {
    fn default() -> Self {
        ObsSpec::paper()
    }
}

/// A caller-provided output buffer.
#[derive(Debug)]
pub enum ObsBufMut<'a> {
    /// For `Dtype::U8`.
    U8(&'a mut [u8]),
    /// For `Dtype::F32`.
    F32(&'a mut [f32]),
}

impl ObsBufMut<'_> {
    fn dtype(&self) -> Dtype {
        match self {
            ObsBufMut::U8(_) => Dtype::U8,
            ObsBufMut::F32(_) => Dtype::F32,
        }
    }
    fn len(&self) -> usize {
        match self {
            ObsBufMut::U8(b) => b.len(),
            ObsBufMut::F32(b) => b.len(),
        }
    }
}

/// An observation could not be written.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ObsError {
    /// The buffer has the wrong number of elements.
    #[error("observation buffer has {got} elements, expected {expected} (shape {shape:?})")]
    WrongLength {
        /// Elements needed.
        expected: usize,
        /// Elements given.
        got: usize,
        /// The observation shape.
        shape: Vec<usize>,
    },
    /// The buffer has the wrong element type.
    #[error("observation buffer has dtype {got}, expected {expected}")]
    WrongDtype {
        /// The spec's dtype.
        expected: Dtype,
        /// The buffer's dtype.
        got: Dtype,
    },
    /// An unknown encoding or dtype name.
    #[error("unknown {what} `{name}`")]
    UnknownName {
        /// "encoding" or "dtype".
        what: &'static str,
        /// The name given.
        name: String,
    },
}

/// The player's status: the original's 9 status values plus gold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Status {
    /// Current floor (1-based).
    pub dungeon_level: u32,
    /// Gold carried.
    pub gold: u32,
    /// Current HP.
    pub hp_current: i32,
    /// Max HP.
    pub hp_max: i32,
    /// Current strength.
    pub str_current: i32,
    /// Max strength.
    pub str_max: i32,
    /// Armour defence (ring mail +1 = 4 at the start).
    pub defense: i32,
    /// Player level.
    pub player_level: u32,
    /// Experience points.
    pub exp: u32,
    /// 0 normal, 1 hungry, 2 weak.
    pub hunger: u32,
}

impl Status {
    /// The 9 values in flag order (dungeon level, hp, max hp, str, max str, defence, level,
    /// exp, hunger).
    pub fn values(&self) -> [i64; 9] {
        [
            i64::from(self.dungeon_level),
            i64::from(self.hp_current),
            i64::from(self.hp_max),
            i64::from(self.str_current),
            i64::from(self.str_max),
            i64::from(self.defense),
            i64::from(self.player_level),
            i64::from(self.exp),
            i64::from(self.hunger),
        ]
    }

    /// The 9 values normalised into [0, 1], in flag order: dungeon level / `amulet_level`,
    /// hp / max hp, max hp / 200, str / max str, max str / 32, defence / 20, player level / 21,
    /// exp / 100000, hunger / 2 (each clamped to [0, 1]).
    pub fn normalized(&self, amulet_level: u32) -> [f32; 9] {
        let r = |v: i64, cap: i64| -> f32 { (v.max(0) as f32 / cap.max(1) as f32).min(1.0) };
        let v = self.values();
        [
            r(v[0], i64::from(amulet_level)),
            r(v[1], v[2]),
            r(v[2], 200),
            r(v[3], v[4]),
            r(v[4], 32),
            r(v[5], 20),
            r(v[6], 21),
            r(v[7], 100_000),
            r(v[8], 2),
        ]
    }
}

/// What an encoder reads: the symbol screen, the ascii screen, the visited plane and status.
pub(crate) struct ObsSource<'a> {
    pub height: usize,
    pub width: usize,
    pub symbols: usize,
    pub sym: &'a [u8],
    pub ascii: &'a [u8],
    pub visited: &'a [u8],
    pub status: Status,
    pub amulet_level: u32,
}

/// Extra planes after the map planes: status planes then history.
fn extra_planes(spec: &ObsSpec) -> usize {
    spec.status.count() + usize::from(spec.history)
}

/// The observation shape for `spec` on an `height` x `width` screen with `symbols` symbols.
pub(crate) fn shape(spec: &ObsSpec, height: usize, width: usize, symbols: usize) -> Vec<usize> {
    let extra = extra_planes(spec);
    match spec.encoding {
        Encoding::SymbolOnehot => vec![symbols + extra, height, width],
        Encoding::Gray => vec![1 + extra, height, width],
        Encoding::SymbolIndex | Encoding::Ascii => {
            if extra == 0 {
                vec![height, width]
            } else {
                vec![1 + extra, height, width]
            }
        }
        Encoding::StatusVector => {
            vec![if spec.status.count() == 0 {
                9
            } else {
                spec.status.count()
            }]
        }
    }
}

/// Writes the observation. Checks dtype and length first; never panics.
pub(crate) fn write(
    spec: &ObsSpec,
    src: &ObsSource<'_>,
    out: ObsBufMut<'_>,
) -> Result<(), ObsError> {
    let shape = shape(spec, src.height, src.width, src.symbols);
    let expected: usize = shape.iter().product();
    if out.dtype() != spec.dtype {
        return Err(ObsError::WrongDtype {
            expected: spec.dtype,
            got: out.dtype(),
        });
    }
    if out.len() != expected {
        return Err(ObsError::WrongLength {
            expected,
            got: out.len(),
            shape,
        });
    }
    let hw = src.height * src.width;
    let status_vals = selected_status(spec, src);
    match out {
        ObsBufMut::U8(buf) => {
            let map_planes = match spec.encoding {
                Encoding::SymbolOnehot => {
                    for (c, plane) in buf.chunks_exact_mut(hw).take(src.symbols).enumerate() {
                        let c = c as u8;
                        for (o, &s) in plane.iter_mut().zip(src.sym) {
                            *o = u8::from(s == c);
                        }
                    }
                    src.symbols
                }
                Encoding::SymbolIndex => {
                    buf[..hw].copy_from_slice(src.sym);
                    1
                }
                Encoding::Ascii => {
                    buf[..hw].copy_from_slice(src.ascii);
                    1
                }
                Encoding::Gray => {
                    let n = src.symbols as u32;
                    for (o, &s) in buf[..hw].iter_mut().zip(src.sym) {
                        *o = (u32::from(s) * 255 / n) as u8;
                    }
                    1
                }
                Encoding::StatusVector => {
                    for (o, v) in buf.iter_mut().zip(status_vals.iter()) {
                        *o = if spec.normalize_status {
                            (v * 255.0).round() as u8
                        } else {
                            v.clamp(0.0, 255.0) as u8
                        };
                    }
                    return Ok(());
                }
            };
            let mut planes = buf[map_planes * hw..].chunks_exact_mut(hw);
            for v in status_vals.iter() {
                let b = if spec.normalize_status {
                    (v * 255.0).round() as u8
                } else {
                    v.clamp(0.0, 255.0) as u8
                };
                if let Some(p) = planes.next() {
                    p.fill(b);
                }
            }
            if spec.history
                && let Some(p) = planes.next()
            {
                p.copy_from_slice(src.visited);
            }
        }
        ObsBufMut::F32(buf) => {
            let map_planes = match spec.encoding {
                Encoding::SymbolOnehot => {
                    for (c, plane) in buf.chunks_exact_mut(hw).take(src.symbols).enumerate() {
                        let c = c as u8;
                        for (o, &s) in plane.iter_mut().zip(src.sym) {
                            *o = if s == c { 1.0 } else { 0.0 };
                        }
                    }
                    src.symbols
                }
                Encoding::SymbolIndex => {
                    for (o, &s) in buf[..hw].iter_mut().zip(src.sym) {
                        *o = f32::from(s);
                    }
                    1
                }
                Encoding::Ascii => {
                    for (o, &s) in buf[..hw].iter_mut().zip(src.ascii) {
                        *o = f32::from(s);
                    }
                    1
                }
                Encoding::Gray => {
                    let n = src.symbols as f32;
                    for (o, &s) in buf[..hw].iter_mut().zip(src.sym) {
                        *o = f32::from(s) / n;
                    }
                    1
                }
                Encoding::StatusVector => {
                    for (o, v) in buf.iter_mut().zip(status_vals.iter()) {
                        *o = *v;
                    }
                    return Ok(());
                }
            };
            let mut planes = buf[map_planes * hw..].chunks_exact_mut(hw);
            for v in status_vals.iter() {
                if let Some(p) = planes.next() {
                    p.fill(*v);
                }
            }
            if spec.history
                && let Some(p) = planes.next()
            {
                for (o, &s) in p.iter_mut().zip(src.visited) {
                    *o = f32::from(s);
                }
            }
        }
    }
    Ok(())
}

/// The selected status values (as f32, raw or normalised), in flag order. For
/// `StatusVector` with empty flags, all 9.
fn selected_status(spec: &ObsSpec, src: &ObsSource<'_>) -> StatusBuf {
    let mut flags = spec.status.0 & 511;
    if spec.encoding == Encoding::StatusVector && flags == 0 {
        flags = 511;
    }
    let mut out = StatusBuf {
        vals: [0.0; 9],
        len: 0,
    };
    if flags == 0 {
        return out;
    }
    let raw = src.status.values();
    let norm = src.status.normalized(src.amulet_level);
    for bit in 0..9 {
        if flags & (1 << bit) != 0 {
            out.vals[out.len] = if spec.normalize_status {
                norm[bit]
            } else {
                raw[bit] as f32
            };
            out.len += 1;
        }
    }
    out
}

/// Up to 9 status values, no allocation.
struct StatusBuf {
    vals: [f32; 9],
    len: usize,
}

impl StatusBuf {
    fn iter(&self) -> std::slice::Iter<'_, f32> {
        self.vals[..self.len].iter()
    }
}
