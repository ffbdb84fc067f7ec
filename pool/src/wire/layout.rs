//! Layout of one worker block in shared memory, and the per-env record.
//!
//! A block is a slice of `u64` words (8-byte aligned):
//! `[records: epw x EnvRecord][obs: epw x obs_bytes, padded to 8][final obs: same, SAME_STEP only]
//! [extra: epw x extra_bytes, padded to 8]`.
//! Observations of the block's envs are contiguous, so a block's observations are one
//! `(epw, *obs_shape)` C-contiguous array.

use crate::env::MAX_INFO;

/// The record says the episode ended by the game's rules.
pub const FLAG_TERMINATED: u32 = 1;
/// The record says the episode was cut (step limit, or worker restart).
pub const FLAG_TRUNCATED: u32 = 2;
/// The env's worker was restarted; the episode was cut and a new one started.
pub const FLAG_RESTARTED: u32 = 4;
/// (SAME_STEP) the block's final-obs area holds this env's final observation.
pub const FLAG_FINAL_OBS: u32 = 8;
/// The env's extra info (`extra_len` bytes) did not fit its room in the block: it travels
/// in the block's side file (`wire::extra_apart_path`).
pub const FLAG_EXTRA_APART: u32 = 16;

/// Per-env scalars of one step, as written by the worker.
///
/// On a step that ends an episode, `episode`, `seed`, `episode_return`, `episode_length` and
/// `info` describe the episode that just ended (also in SAME_STEP mode, where the observation is
/// already the next episode's first). On a reset (or the NEXT_STEP reset step) they describe the
/// new episode (return 0, length 0).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[repr(C)]
pub struct EnvRecord {
    /// Reward of the step (0 on resets).
    pub reward: f64,
    /// `FLAG_*` bits.
    pub flags: u32,
    /// Steps taken in the episode so far (including this step).
    pub episode_length: u32,
    /// Sum of the episode's rewards so far (including this step).
    pub episode_return: f64,
    /// Episode index of the env (0, 1, 2, ...): the `e` of the seed schedule.
    pub episode: u64,
    /// Seed of the episode.
    pub seed: u64,
    /// Bytes of extra info the env wrote into the block's extra area (see
    /// `EnvSpec::extra_bytes`); 0: none.
    pub extra_len: u32,
    /// Reserved (zero).
    pub reserved: u32,
    /// Env-defined info values (see `EnvSpec::info_names`); unused entries are 0.
    pub info: [f64; MAX_INFO],
}

impl EnvRecord {
    /// `terminated` flag.
    pub fn terminated(&self) -> bool {
        self.flags & FLAG_TERMINATED != 0
    }
    /// `truncated` flag.
    pub fn truncated(&self) -> bool {
        self.flags & FLAG_TRUNCATED != 0
    }
    /// Worker-restart flag.
    pub fn restarted(&self) -> bool {
        self.flags & FLAG_RESTARTED != 0
    }
    /// Whether a final observation is available (SAME_STEP).
    pub fn has_final_obs(&self) -> bool {
        self.flags & FLAG_FINAL_OBS != 0
    }
    /// Whether the extra info is in the block's side file.
    pub fn extra_apart(&self) -> bool {
        self.flags & FLAG_EXTRA_APART != 0
    }
}

/// Words per record.
pub const RECORD_WORDS: usize = std::mem::size_of::<EnvRecord>() / 8;
const _: () = assert!(std::mem::size_of::<EnvRecord>().is_multiple_of(8));
const _: () = assert!(std::mem::align_of::<EnvRecord>() == 8);

/// Geometry of a worker block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockLayout {
    /// Envs per block.
    pub envs: usize,
    /// Bytes per observation.
    pub obs_bytes: usize,
    /// Whether the block has a final-obs area (SAME_STEP).
    pub final_obs: bool,
    /// Bytes of extra info room per env (0: no extra area).
    pub extra_bytes: usize,
}

impl BlockLayout {
    fn obs_area_words(&self) -> usize {
        (self.envs * self.obs_bytes).div_ceil(8)
    }
    /// Word offset of the observation area.
    pub fn obs_offset_words(&self) -> usize {
        self.envs * RECORD_WORDS
    }
    /// Word offset of the final-observation area.
    pub fn final_offset_words(&self) -> usize {
        self.obs_offset_words() + self.obs_area_words()
    }
    /// Word offset of the extra-info area.
    pub fn extra_offset_words(&self) -> usize {
        self.final_offset_words()
            + if self.final_obs {
                self.obs_area_words()
            } else {
                0
            }
    }
    /// Bytes of a block besides its observation area (records, final observations, extra
    /// infos): what a block adds in shared memory when observations go to the batch buffer.
    pub fn side_bytes(&self) -> usize {
        (self.words() - self.obs_area_words()) * 8
    }
    /// Total words of a block.
    pub fn words(&self) -> usize {
        self.extra_offset_words() + (self.envs * self.extra_bytes).div_ceil(8)
    }

    /// Read record `j` of a block.
    pub fn record(&self, block: &[u64], j: usize) -> EnvRecord {
        let w = &block[j * RECORD_WORDS..(j + 1) * RECORD_WORDS];
        // SAFETY: `w` is 8-byte aligned, long enough, and every bit pattern is a valid
        // EnvRecord (integers and floats only).
        unsafe { std::ptr::read(w.as_ptr().cast::<EnvRecord>()) }
    }

    /// Write record `j` of a block.
    pub fn write_record(&self, block: &mut [u64], j: usize, r: &EnvRecord) {
        let w = &mut block[j * RECORD_WORDS..(j + 1) * RECORD_WORDS];
        // SAFETY: as in `record`; the slice is exclusively borrowed.
        unsafe { std::ptr::write(w.as_mut_ptr().cast::<EnvRecord>(), *r) }
    }

    /// The observation bytes of all envs of the block (`envs * obs_bytes`).
    pub fn obs<'a>(&self, block: &'a [u64]) -> &'a [u8] {
        let b = rogue_gym_ipc::words_as_bytes(&block[self.obs_offset_words()..]);
        &b[..self.envs * self.obs_bytes]
    }

    /// The final-observation bytes of all envs (SAME_STEP), if the block has them.
    pub fn final_obs<'a>(&self, block: &'a [u64]) -> Option<&'a [u8]> {
        if !self.final_obs {
            return None;
        }
        let b = rogue_gym_ipc::words_as_bytes(&block[self.final_offset_words()..]);
        Some(&b[..self.envs * self.obs_bytes])
    }

    /// The extra info env `j` wrote (`extra_len` bytes of its record), empty if none.
    pub fn extra<'a>(&self, block: &'a [u64], j: usize, extra_len: u32) -> &'a [u8] {
        let n = (extra_len as usize).min(self.extra_bytes);
        let b = rogue_gym_ipc::words_as_bytes(&block[self.extra_offset_words()..]);
        &b[j * self.extra_bytes..j * self.extra_bytes + n]
    }

    /// Split a block into its areas for writing.
    pub fn split_mut<'a>(&self, block: &'a mut [u64]) -> BlockAreas<'a> {
        let (rec, rest) = block.split_at_mut(self.obs_offset_words());
        let (obs, rest) = rest.split_at_mut(self.obs_area_words());
        let (fin, extra) = rest.split_at_mut(self.extra_offset_words() - self.final_offset_words());
        let n = self.envs * self.obs_bytes;
        let obs = &mut rogue_gym_ipc::words_as_bytes_mut(obs)[..n];
        let fin = &mut rogue_gym_ipc::words_as_bytes_mut(fin)[..if self.final_obs { n } else { 0 }];
        let extra = &mut rogue_gym_ipc::words_as_bytes_mut(extra)[..self.envs * self.extra_bytes];
        BlockAreas {
            records: rec,
            obs,
            final_obs: fin,
            extra,
        }
    }
}

/// The writable areas of a block (see [`BlockLayout::split_mut`]).
pub struct BlockAreas<'a> {
    /// The records (`envs x RECORD_WORDS` words).
    pub records: &'a mut [u64],
    /// The observations (`envs x obs_bytes`).
    pub obs: &'a mut [u8],
    /// The final observations (SAME_STEP; empty otherwise).
    pub final_obs: &'a mut [u8],
    /// The extra-info room (`envs x extra_bytes`).
    pub extra: &'a mut [u8],
}

/// Write a record into a records area (as returned by [`BlockLayout::split_mut`]).
pub fn write_record_words(records: &mut [u64], j: usize, r: &EnvRecord) {
    let w = &mut records[j * RECORD_WORDS..(j + 1) * RECORD_WORDS];
    // SAFETY: see BlockLayout::record.
    unsafe { std::ptr::write(w.as_mut_ptr().cast::<EnvRecord>(), *r) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_and_areas_do_not_overlap() {
        let l = BlockLayout {
            envs: 3,
            obs_bytes: 5,
            final_obs: true,
            extra_bytes: 6,
        };
        let mut block = vec![0u64; l.words()];
        let r = EnvRecord {
            reward: 1.5,
            flags: FLAG_TRUNCATED,
            episode: 7,
            seed: 99,
            info: [1.0; MAX_INFO],
            ..Default::default()
        };
        {
            let a = l.split_mut(&mut block);
            write_record_words(a.records, 1, &r);
            a.obs.fill(0xAA);
            a.final_obs.fill(0xBB);
            a.extra.fill(0xCC);
        }
        assert_eq!(l.record(&block, 1), r);
        assert_eq!(l.extra(&block, 2, 4), &[0xCC; 4]);
        assert_eq!(l.extra(&block, 2, 99).len(), 6, "clamped to the room");
        assert_eq!(l.record(&block, 0), EnvRecord::default());
        assert!(l.obs(&block).iter().all(|&b| b == 0xAA));
        assert!(l.final_obs(&block).unwrap().iter().all(|&b| b == 0xBB));
        assert_eq!(l.obs(&block).len(), 15);
    }
}
