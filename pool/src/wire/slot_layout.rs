//! Layout of one slot of the shared batch buffer: every per-env output of an answer (a
//! whole-batch call's, an async env's), written in place by the worker that served the env,
//! at the env's row, where the caller reads it.
//!
//! A slot is `[obs: num_envs x obs_bytes][columns][final obs (SAME_STEP)][extra room]`, each
//! area 64-byte aligned. The columns are one array per value, `num_envs` entries each, 8-byte
//! values first, then 4-byte, then 1-byte ([`COLUMNS`]); the `info_*` columns have one such
//! row per info value. Each row starts 64-byte aligned and one cache line past a multiple of
//! 64 bytes ([`ROW_SKEW`]): rows of a power-of-two size would otherwise all map to the same
//! cache sets, and a worker writing one entry of each for every env would evict its own lines
//! (at 4096 envs that cost the workers 40% of their time).

use crate::env::MAX_INFO;
use crate::wire::record::EnvRecord;

/// One column of a slot: its name (as the Python front knows it), numpy dtype name, bytes per
/// entry, and rows (1, or one per info value for the `info_*` columns).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Column {
    /// Name.
    pub name: &'static str,
    /// numpy dtype name.
    pub dtype: &'static str,
    /// Bytes per entry.
    pub size: usize,
    /// Rows of `num_envs` entries (the `info_*` columns have one per info value).
    pub per_info: bool,
}

const fn col(name: &'static str, dtype: &'static str, size: usize, per_info: bool) -> Column {
    Column {
        name,
        dtype,
        size,
        per_info,
    }
}

/// The columns of a slot, in memory order (8-byte entries first, so every column is aligned).
pub const COLUMNS: [Column; 12] = [
    col("reward", "float64", 8, false),
    col("seed", "uint64", 8, false),
    col("episode_index", "int64", 8, false),
    col("episode_return", "float64", 8, false),
    col("episode_length", "int64", 8, false),
    col("info_int", "int64", 8, true),
    col("extra_len", "uint32", 4, false),
    col("terminated", "bool", 1, false),
    col("truncated", "bool", 1, false),
    col("restarted", "bool", 1, false),
    col("has_final_obs", "bool", 1, false),
    col("info_bool", "bool", 1, true),
];

// Indices into COLUMNS.
const REWARD: usize = 0;
const SEED: usize = 1;
const EPISODE: usize = 2;
const RETURN: usize = 3;
const LENGTH: usize = 4;
const INFO_INT: usize = 5;
const EXTRA_LEN: usize = 6;
const TERMINATED: usize = 7;
const TRUNCATED: usize = 8;
const RESTARTED: usize = 9;
const HAS_FINAL: usize = 10;
const INFO_BOOL: usize = 11;

fn align64(n: usize) -> usize {
    n.div_ceil(64) * 64
}

/// Bytes each column row is shifted by past its 64-byte aligned size, so that the rows of a
/// slot start in different cache sets.
pub const ROW_SKEW: usize = 64;

/// A column of flags, one byte per env ([`SlotRows::check_flags`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flag {
    /// `terminated`.
    Terminated,
    /// `truncated`.
    Truncated,
    /// `restarted`.
    Restarted,
    /// `has_final_obs`.
    HasFinalObs,
    /// Row `j` of `info_bool`.
    Info(usize),
}

/// A column as a caller views it: `(name, numpy dtype, byte offset from the columns area,
/// rows, bytes from one row to the next)`.
pub type ColumnView = (&'static str, &'static str, usize, usize, usize);

/// Geometry of a slot (the same for every slot of a pool).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SlotLayout {
    /// Envs of the pool (rows of every column).
    pub num_envs: usize,
    /// Bytes of one observation.
    pub obs_bytes: usize,
    /// Info values per env (rows of the `info_*` columns).
    pub n_info: usize,
    /// Whether the slot has a final-observation area (SAME_STEP).
    pub final_obs: bool,
    /// Bytes of extra-info room per env (0: no extra area).
    pub extra_bytes: usize,
}

impl SlotLayout {
    fn rows_of(&self, c: &Column) -> usize {
        if c.per_info { self.n_info } else { 1 }
    }
    /// Bytes from one row of column `c` to the next.
    fn row_stride(&self, c: &Column) -> usize {
        align64(c.size * self.num_envs) + ROW_SKEW
    }
    /// Byte offset of the columns area.
    pub fn columns_offset(&self) -> usize {
        align64(self.num_envs * self.obs_bytes)
    }
    /// Byte offset of column `i` of [`COLUMNS`] from the slot's start.
    fn column_offset(&self, i: usize) -> usize {
        self.columns_offset()
            + COLUMNS[..i]
                .iter()
                .map(|c| self.rows_of(c) * self.row_stride(c))
                .sum::<usize>()
    }
    /// Bytes of the columns area.
    pub fn columns_bytes(&self) -> usize {
        align64(self.column_offset(COLUMNS.len()) - self.columns_offset())
    }
    /// Byte offset of the final-observation area (meaningful when `final_obs`).
    pub fn final_offset(&self) -> usize {
        self.columns_offset() + self.columns_bytes()
    }
    /// Byte offset of the extra-info room (`num_envs x extra_bytes`).
    pub fn extra_offset(&self) -> usize {
        self.final_offset()
            + if self.final_obs {
                align64(self.num_envs * self.obs_bytes)
            } else {
                0
            }
    }
    /// Bytes of one slot (64-byte aligned).
    pub fn bytes(&self) -> usize {
        self.extra_offset() + align64(self.num_envs * self.extra_bytes)
    }
    /// The columns as `(name, numpy dtype, byte offset from the columns area, rows, bytes
    /// from row to row)`, and the columns area's size: what a caller needs to view them.
    pub fn column_views(&self) -> (Vec<ColumnView>, usize) {
        let base = self.columns_offset();
        let v = COLUMNS
            .iter()
            .enumerate()
            .map(|(i, c)| {
                (
                    c.name,
                    c.dtype,
                    self.column_offset(i) - base,
                    self.rows_of(c),
                    self.row_stride(c),
                )
            })
            .collect();
        (v, self.columns_bytes())
    }

    /// The rows of the slot starting at `base`.
    ///
    /// # Safety
    /// `base` must point to a slot of this layout in a live mapping, 64-byte aligned; the
    /// rows written through the value must be this side's to write (see [`SlotRows`]).
    pub unsafe fn rows(&self, base: *mut u8) -> SlotRows {
        let mut offsets = [0usize; COLUMNS.len()];
        let mut strides = [0usize; COLUMNS.len()];
        for (i, c) in COLUMNS.iter().enumerate() {
            offsets[i] = self.column_offset(i);
            strides[i] = self.row_stride(c);
        }
        SlotRows {
            base,
            layout: *self,
            offsets,
            strides,
        }
    }
}

/// The rows of one slot: a worker writes its envs' rows in place (the supervisor the rows of
/// a restarted worker), and the caller reads them there. Holds a raw pointer into the shared
/// mapping: who writes which rows when is the pool's protocol (a worker writes its block's
/// rows of the slot a command names, and no one reads them until the answer arrives).
#[derive(Debug, Clone, Copy)]
pub struct SlotRows {
    base: *mut u8,
    layout: SlotLayout,
    offsets: [usize; COLUMNS.len()],
    strides: [usize; COLUMNS.len()],
}

// SAFETY: a plain pointer into a shared mapping that outlives the writer; the protocol
// (documented on the type) keeps writers of one row apart.
unsafe impl Send for SlotRows {}

impl SlotRows {
    /// The slot's layout.
    pub fn layout(&self) -> SlotLayout {
        self.layout
    }
    /// Entry `row` of row `j` of column `col` (`j` is 0 but for the `info_*` columns).
    #[inline]
    fn at<T>(&self, col: usize, j: usize, row: usize) -> *mut T {
        debug_assert!(row <= self.layout.num_envs && j < self.layout.n_info.max(1));
        // SAFETY: the offset stays inside the slot (see `SlotLayout`).
        unsafe {
            self.base
                .add(self.offsets[col] + j * self.strides[col])
                .cast::<T>()
                .add(row)
        }
    }
    #[inline]
    fn put<T>(&self, col: usize, row: usize, v: T) {
        // SAFETY: in bounds and aligned (every row is 64-byte aligned).
        unsafe { self.at::<T>(col, 0, row).write(v) }
    }
    #[inline]
    fn put_info<T>(&self, col: usize, j: usize, row: usize, v: T) {
        // SAFETY: as in `put`.
        unsafe { self.at::<T>(col, j, row).write(v) }
    }
    /// Write env `row`'s record: reward, flags, episode books, info values (as integers and
    /// flags) and the length of its extra info.
    #[inline]
    pub fn record(&self, row: usize, r: &EnvRecord) {
        let n = self.layout.num_envs;
        assert!(row < n, "row {row} of a slot of {n} envs");
        self.put(REWARD, row, r.reward);
        self.put(SEED, row, r.seed);
        self.put(EPISODE, row, r.episode);
        self.put(RETURN, row, r.episode_return);
        self.put(LENGTH, row, i64::from(r.episode_length));
        let k = self.layout.n_info.min(MAX_INFO);
        for (j, v) in r.info[..k].iter().enumerate() {
            self.put_info(INFO_INT, j, row, *v as i64);
            self.put_info(INFO_BOOL, j, row, u8::from(*v != 0.0));
        }
        self.put(
            EXTRA_LEN,
            row,
            if r.extra_apart() { 0 } else { r.extra_len },
        );
        self.put(TERMINATED, row, u8::from(r.terminated()));
        self.put(TRUNCATED, row, u8::from(r.truncated()));
        self.put(RESTARTED, row, u8::from(r.restarted()));
        self.put(HAS_FINAL, row, u8::from(r.has_final_obs()));
    }
    /// Check that the bytes of flag column `flag` at rows `rows` are each 0 or 1: what a
    /// caller hands out as `bool` must be one. The error names the column and the env.
    pub fn check_flags(&self, flag: Flag, rows: std::ops::Range<usize>) -> Result<(), String> {
        let n = self.layout.num_envs;
        let (c, j) = match flag {
            Flag::Terminated => (TERMINATED, 0),
            Flag::Truncated => (TRUNCATED, 0),
            Flag::Restarted => (RESTARTED, 0),
            Flag::HasFinalObs => (HAS_FINAL, 0),
            Flag::Info(j) if j < self.layout.n_info.min(MAX_INFO) => (INFO_BOOL, j),
            Flag::Info(j) => return Err(format!("no info row {j}")),
        };
        if rows.start > rows.end || rows.end > n {
            return Err(format!("rows {rows:?} of a slot of {n} envs"));
        }
        // SAFETY: in bounds (checked above) and plain bytes.
        let bytes =
            unsafe { std::slice::from_raw_parts(self.at::<u8>(c, j, rows.start), rows.len()) };
        // One pass that the compiler vectorizes; the error path finds the env.
        if bytes.iter().fold(0u8, |a, &b| a | b) <= 1 {
            return Ok(());
        }
        let r = bytes.iter().position(|&b| b > 1).unwrap_or(0);
        Err(format!(
            "flag byte {} in the {} column{} of env {}",
            bytes[r],
            COLUMNS[c].name,
            if c == INFO_BOOL {
                format!(" (info {j})")
            } else {
                String::new()
            },
            rows.start + r
        ))
    }

    /// Mark env `row` as restarted: its episode was cut (truncated, reward 0).
    pub fn mark_restarted(&self, row: usize) {
        assert!(row < self.layout.num_envs);
        self.put(REWARD, row, 0.0f64);
        self.put(TERMINATED, row, 0u8);
        self.put(TRUNCATED, row, 1u8);
        self.put(RESTARTED, row, 1u8);
        self.put(HAS_FINAL, row, 0u8);
    }
    /// Write byte `byte` as env `row`'s flag `flag` (a worker's misdeed:
    /// [`crate::wire::sabotage`]).
    pub(crate) fn write_flag_byte(&self, flag: Flag, row: usize, byte: u8) {
        assert!(row < self.layout.num_envs);
        let (c, j) = match flag {
            Flag::Terminated => (TERMINATED, 0),
            Flag::Truncated => (TRUNCATED, 0),
            Flag::Restarted => (RESTARTED, 0),
            Flag::HasFinalObs => (HAS_FINAL, 0),
            Flag::Info(j) => (INFO_BOOL, j.min(self.layout.n_info.saturating_sub(1))),
        };
        self.put_info(c, j, row, byte);
    }
    /// Write env `row`'s extra-info length alone (a worker's misdeed).
    pub(crate) fn write_extra_len(&self, row: usize, len: u32) {
        assert!(row < self.layout.num_envs);
        self.put(EXTRA_LEN, row, len);
    }
    /// Clear env `row`'s `restarted` flag (its worker was not restarted).
    pub fn clear_restarted(&self, row: usize) {
        assert!(row < self.layout.num_envs);
        self.put(RESTARTED, row, 0u8);
    }
    /// Read env `row`'s values back as a record (flags, reward, books and info values; the
    /// Rust API's copying forms use it).
    pub fn read(&self, row: usize) -> EnvRecord {
        assert!(row < self.layout.num_envs);
        use crate::wire::record::{
            FLAG_FINAL_OBS, FLAG_RESTARTED, FLAG_TERMINATED, FLAG_TRUNCATED,
        };
        // SAFETY: in bounds and aligned, as in `put`.
        let get = |col: usize, j: usize| unsafe { self.at::<u64>(col, j, row).read() };
        let flag = |col: usize, bit: u32| {
            // SAFETY: as above.
            if unsafe { self.at::<u8>(col, 0, row).read() } != 0 {
                bit
            } else {
                0
            }
        };
        let mut r = EnvRecord {
            reward: f64::from_bits(get(REWARD, 0)),
            seed: get(SEED, 0),
            episode: get(EPISODE, 0),
            episode_return: f64::from_bits(get(RETURN, 0)),
            episode_length: get(LENGTH, 0) as u32,
            flags: flag(TERMINATED, FLAG_TERMINATED)
                | flag(TRUNCATED, FLAG_TRUNCATED)
                | flag(RESTARTED, FLAG_RESTARTED)
                | flag(HAS_FINAL, FLAG_FINAL_OBS),
            // SAFETY: as above.
            extra_len: unsafe { self.at::<u32>(EXTRA_LEN, 0, row).read() },
            ..Default::default()
        };
        for j in 0..self.layout.n_info.min(MAX_INFO) {
            r.info[j] = get(INFO_INT, j) as i64 as f64;
        }
        r
    }
    /// Rows `rows` of an area of `per_row` bytes per env at `offset`.
    ///
    /// # Safety
    /// No one else may access those rows meanwhile.
    unsafe fn area<'a>(
        &self,
        offset: usize,
        per_row: usize,
        rows: std::ops::Range<usize>,
    ) -> &'a mut [u8] {
        debug_assert!(rows.end <= self.layout.num_envs);
        unsafe {
            std::slice::from_raw_parts_mut(
                self.base.add(offset + rows.start * per_row),
                rows.len() * per_row,
            )
        }
    }
    /// The observations of rows `rows` (`rows.len() x obs_bytes`).
    ///
    /// # Safety
    /// No one else may access those rows meanwhile.
    pub unsafe fn obs_rows<'a>(&self, rows: std::ops::Range<usize>) -> &'a mut [u8] {
        unsafe { self.area(0, self.layout.obs_bytes, rows) }
    }
    /// The final observations of rows `rows` (SAME_STEP; empty without a final area).
    ///
    /// # Safety
    /// No one else may access those rows meanwhile.
    pub unsafe fn final_rows<'a>(&self, rows: std::ops::Range<usize>) -> &'a mut [u8] {
        if !self.layout.final_obs {
            return &mut [];
        }
        unsafe { self.area(self.layout.final_offset(), self.layout.obs_bytes, rows) }
    }
    /// Copy env `row`'s observation, final observation and record from slot `from` (of the
    /// same layout) into this slot.
    ///
    /// # Safety
    /// No one else may access row `row` of either slot meanwhile, and the slots differ.
    pub unsafe fn copy_row(&self, from: &SlotRows, row: usize) {
        let r = row..row + 1;
        unsafe {
            self.obs_rows(r.clone())
                .copy_from_slice(from.obs_rows(r.clone()));
            self.final_rows(r.clone())
                .copy_from_slice(from.final_rows(r));
        }
        self.record(row, &from.read(row));
    }
    /// The extra-info room of rows `rows` (`rows.len() x extra_bytes`).
    ///
    /// # Safety
    /// No one else may access those rows meanwhile.
    pub unsafe fn extra_rows<'a>(&self, rows: std::ops::Range<usize>) -> &'a mut [u8] {
        unsafe { self.area(self.layout.extra_offset(), self.layout.extra_bytes, rows) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::record::{FLAG_FINAL_OBS, FLAG_TERMINATED};

    #[test]
    fn areas_are_aligned_and_apart_and_a_row_round_trips() {
        let l = SlotLayout {
            num_envs: 5,
            obs_bytes: 7,
            n_info: 3,
            final_obs: true,
            extra_bytes: 12,
        };
        for off in [
            l.columns_offset(),
            l.final_offset(),
            l.extra_offset(),
            l.bytes(),
        ] {
            assert_eq!(off % 64, 0);
        }
        assert!(l.columns_offset() >= 35 && l.final_offset() - l.columns_offset() >= 5 * 73);
        let (cols, bytes) = l.column_views();
        assert_eq!(cols.len(), COLUMNS.len());
        assert!(
            cols.iter()
                .zip(COLUMNS)
                .all(|(c, d)| c.2 + c.4 * c.3 <= bytes && c.4 >= 5 * d.size)
        );
        // At a power-of-two number of envs, no two rows start in the same cache set.
        let big = SlotLayout {
            num_envs: 4096,
            ..l
        };
        let starts: Vec<usize> = big
            .column_views()
            .0
            .iter()
            .flat_map(|c| (0..c.3).map(move |j| (c.2 + j * c.4) % 4096))
            .collect();
        let mut distinct = starts.clone();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(distinct.len(), starts.len(), "{starts:?}");
        assert!(starts.iter().all(|s| s % 64 == 0));
        assert!(cols.windows(2).all(|w| w[0].2 < w[1].2));
        let mut slot = vec![0u64; l.bytes() / 8];
        // SAFETY: a buffer of the layout's size, 8-aligned (the test does not need 64).
        let w = unsafe { l.rows(slot.as_mut_ptr().cast()) };
        let r = EnvRecord {
            reward: 2.5,
            flags: FLAG_TERMINATED | FLAG_FINAL_OBS,
            episode_length: 9,
            episode_return: 11.0,
            episode: 3,
            seed: 77,
            extra_len: 4,
            info: [1.0, 0.0, 6.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            ..Default::default()
        };
        w.record(4, &r);
        assert_eq!(w.read(4), r);
        assert_eq!(w.read(3), EnvRecord::default(), "other rows untouched");
        w.mark_restarted(4);
        let m = w.read(4);
        assert!(m.truncated() && m.restarted() && !m.terminated() && m.reward == 0.0);
    }
}
