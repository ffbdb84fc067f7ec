//! The per-env record of one reset or step, as an env's state machine makes it and a slot's
//! columns hold it ([`super::slot_layout::SlotRows::record`]), and its flags.

use crate::env::MAX_INFO;

/// The record says the episode ended by the game's rules.
pub const FLAG_TERMINATED: u32 = 1;
/// The record says the episode was cut (step limit, or worker restart).
pub const FLAG_TRUNCATED: u32 = 2;
/// The env's worker was restarted; the episode was cut and a new one started.
pub const FLAG_RESTARTED: u32 = 4;
/// (SAME_STEP) the slot's final-obs area holds this env's final observation.
pub const FLAG_FINAL_OBS: u32 = 8;
/// The env's extra info (`extra_len` bytes) did not fit its room in the slot: it travels
/// in the answer's side file (`wire::extra_apart_path`).
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

const _: () = assert!(std::mem::size_of::<EnvRecord>().is_multiple_of(8));
const _: () = assert!(std::mem::align_of::<EnvRecord>() == 8);
