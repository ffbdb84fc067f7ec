//! What to encode ([`ObsSpec`]: encoding, dtype, status planes, history) and where
//! ([`ObsBufMut`]), with its errors.

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
            "symbol_onehot" | "onehot" => Encoding::SymbolOnehot,
            "symbol_index" | "index" => Encoding::SymbolIndex,
            "gray" => Encoding::Gray,
            "ascii" => Encoding::Ascii,
            "status" | "status_vector" => Encoding::StatusVector,
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
    /// The one parser of an observation spec, from its JSON object form
    /// `{"encoding": .., "dtype": .., "status": bits, "normalize_status": .., "history": ..}`;
    /// absent keys (or `null`) take [`ObsSpec::paper`]'s values. Errors name the key.
    pub fn from_json(v: &serde_json::Value) -> Result<ObsSpec, ObsError> {
        let mut s = ObsSpec::paper();
        if v.is_null() {
            return Ok(s);
        }
        let o = v
            .as_object()
            .ok_or_else(|| ObsError::Invalid(format!("must be an object, got {v}")))?;
        for (k, x) in o {
            let bad = |want: &str| ObsError::Invalid(format!("{k} must be {want}, got {x}"));
            match k.as_str() {
                "encoding" => s.encoding = x.as_str().ok_or_else(|| bad("a string"))?.parse()?,
                "dtype" => s.dtype = x.as_str().ok_or_else(|| bad("a string"))?.parse()?,
                "status" => {
                    let bits = x
                        .as_u64()
                        .filter(|b| *b <= u64::from(StatusFlags::FULL.0))
                        .ok_or_else(|| {
                            bad(&format!("a bit mask in 0..={:#x}", StatusFlags::FULL.0))
                        })?;
                    s.status = StatusFlags(bits as u16);
                }
                "normalize_status" => {
                    s.normalize_status = x.as_bool().ok_or_else(|| bad("a bool"))?
                }
                "history" => s.history = x.as_bool().ok_or_else(|| bad("a bool"))?,
                _ => {
                    return Err(ObsError::Invalid(format!(
                        "unknown key {k:?} (known: encoding, dtype, status, normalize_status, history)"
                    )));
                }
            }
        }
        Ok(s)
    }

    /// The spec's JSON object form (read back by [`ObsSpec::from_json`]).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "encoding": self.encoding.to_string(),
            "dtype": match self.dtype {
                Dtype::U8 => "uint8",
                Dtype::F32 => "float32",
            },
            "status": self.status.0,
            "normalize_status": self.normalize_status,
            "history": self.history,
        })
    }

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
    pub(crate) fn dtype(&self) -> Dtype {
        match self {
            ObsBufMut::U8(_) => Dtype::U8,
            ObsBufMut::F32(_) => Dtype::F32,
        }
    }
    pub(crate) fn len(&self) -> usize {
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
    /// A malformed observation spec (a wrong key or value type).
    #[error("observation spec: {0}")]
    Invalid(String),
    /// An unknown encoding or dtype name.
    #[error("unknown observation {what} `{name}`: expected one of {}", if *what == "encoding" { "symbol_onehot, symbol_index, gray, ascii, status" } else { "uint8, float32" })]
    UnknownName {
        /// "encoding" or "dtype".
        what: &'static str,
        /// The name given.
        name: String,
    },
}
