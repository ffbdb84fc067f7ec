//! What a call hands back: the answer of a whole-batch call ([`SlotAnswer`]), its rows copied
//! out ([`BatchOutput`]), and a worker's block of the async API ([`Block`]).

use std::ops::Range;

use rogue_gym_ipc::BlockSample;

use crate::wire::layout::{BlockLayout, EnvRecord, FLAG_RESTARTED, FLAG_TRUNCATED};

/// Per-env arrays of one batch, copied out of a slot ([`crate::Pool::read_slot`]). Row `r`
/// describes env `env_ids[r]`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BatchOutput {
    /// Env ids of the rows.
    pub env_ids: Vec<usize>,
    /// Rewards.
    pub reward: Vec<f64>,
    /// Episode ended by the rules.
    pub terminated: Vec<bool>,
    /// Episode cut (step limit or worker restart).
    pub truncated: Vec<bool>,
    /// The env's worker was restarted (its episode was cut; the obs is a new episode's first).
    pub restarted: Vec<bool>,
    /// Episode return so far (of the ended episode on a final step).
    pub episode_return: Vec<f64>,
    /// Episode length so far.
    pub episode_length: Vec<u32>,
    /// Episode index (the `e` of the seed schedule).
    pub episode: Vec<u64>,
    /// Episode seed.
    pub seed: Vec<u64>,
    /// Env-defined info values, row-major `rows x info_names.len()`.
    pub info: Vec<f64>,
    /// (SAME_STEP) whether `final_obs` row `r` is valid.
    pub has_final_obs: Vec<bool>,
    /// (SAME_STEP) final observations, `rows x obs_bytes`; empty in NEXT_STEP mode.
    pub final_obs: Vec<u8>,
    /// `(env id, bytes)` of the envs that wrote extra info ([`crate::Env::extra_info`]), in
    /// row order; only those.
    pub extras: Vec<(usize, Vec<u8>)>,
}

impl BatchOutput {
    pub(crate) fn clear(&mut self) {
        self.env_ids.clear();
        self.reward.clear();
        self.terminated.clear();
        self.truncated.clear();
        self.restarted.clear();
        self.episode_return.clear();
        self.episode_length.clear();
        self.episode.clear();
        self.seed.clear();
        self.info.clear();
        self.has_final_obs.clear();
        self.final_obs.clear();
        self.extras.clear();
    }

    /// Append env `env`'s row: its record (the first `n_info` infos) and, where `fin` is the
    /// room of its final observation, that observation when the record says it has one.
    pub fn push(&mut self, env: usize, r: &EnvRecord, n_info: usize, fin: Option<&[u8]>) {
        self.env_ids.push(env);
        self.reward.push(r.reward);
        self.terminated.push(r.terminated());
        self.truncated.push(r.truncated());
        self.restarted.push(r.restarted());
        self.episode_return.push(r.episode_return);
        self.episode_length.push(r.episode_length);
        self.episode.push(r.episode);
        self.seed.push(r.seed);
        self.info.extend_from_slice(&r.info[..n_info]);
        if let Some(f) = fin {
            self.has_final_obs.push(r.has_final_obs());
            if r.has_final_obs() {
                self.final_obs.extend_from_slice(f);
            } else {
                self.final_obs.resize(self.final_obs.len() + f.len(), 0);
            }
        } else {
            self.has_final_obs.push(false);
        }
    }
}

/// What a whole-batch call (step, reset, partial reset) answers beside the rows the workers
/// wrote in place in its batch slot ([`crate::wire::slot_layout`]): found out from one word
/// per worker, never by reading the envs' rows.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SlotAnswer {
    /// The slot the workers wrote.
    pub slot: usize,
    /// Some env's worker was restarted during the call (its rows say `restarted`).
    pub restarted: bool,
    /// (SAME_STEP) some env has a final observation in the slot's final area.
    pub final_obs: bool,
    /// The envs' extra info.
    pub extras: SlotExtras,
}

/// The extra info of a whole-batch call ([`crate::Env::extra_info`]: hosted envs' infos).
#[derive(Debug, Clone, Default, PartialEq)]
pub enum SlotExtras {
    /// No env wrote any.
    #[default]
    None,
    /// Every env wrote this many bytes of one layout (the same first 16 bytes), each in its
    /// room of the slot's extra area: read them there.
    Uniform(usize),
    /// Some envs wrote some, not all of one layout: `(env, bytes)` in env order (collected
    /// env by env: the irregular case, e.g. infos that are pickled).
    Rows(Vec<(usize, Vec<u8>)>),
}

/// One worker's block as received: an owned handle on the shared-memory sample (`Send`).
///
/// Lifetime: the observation bytes stay valid and unchanged for as long as the `Block` lives,
/// even after the pool is closed. Each held block pins one of its worker's
/// `max_borrowed` sample slots: holding `max_borrowed` blocks of one worker makes the next
/// receive from that worker fail, so keep at most `max_borrowed - 1` per worker.
pub struct Block {
    pub(crate) worker: usize,
    pub(crate) env_start: usize,
    pub(crate) layout: BlockLayout,
    pub(crate) restarted: bool,
    pub(crate) sample: BlockSample,
    /// Extra info of the rows flagged `FLAG_EXTRA_APART`, from the block's side file.
    pub(crate) apart: Vec<(u32, Vec<u8>)>,
}

impl std::fmt::Debug for Block {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Block")
            .field("worker", &self.worker)
            .field("env_ids", &self.env_ids())
            .finish()
    }
}

impl Block {
    /// The worker that produced it.
    pub fn worker(&self) -> usize {
        self.worker
    }
    /// Env ids of its rows.
    pub fn env_ids(&self) -> Range<usize> {
        self.env_start..self.env_start + self.layout.envs
    }
    /// Its observations: `envs x obs_bytes` C-contiguous bytes in shared memory (read-only),
    /// 8-byte aligned.
    pub fn obs(&self) -> &[u8] {
        self.layout.obs(self.sample.payload())
    }
    /// (SAME_STEP) its final observations, same layout as [`Block::obs`].
    pub fn final_obs(&self) -> Option<&[u8]> {
        self.layout.final_obs(self.sample.payload())
    }
    /// Extra info of row `j` (empty if the env wrote none).
    pub fn extra(&self, j: usize) -> &[u8] {
        let r = self.layout.record(self.sample.payload(), j);
        if r.extra_apart() {
            return self
                .apart
                .iter()
                .find(|(row, _)| *row as usize == j)
                .map_or(&[], |(_, b)| b.as_slice());
        }
        self.layout.extra(self.sample.payload(), j, r.extra_len)
    }
    /// Record of row `j` (with the restart flags applied).
    pub fn record(&self, j: usize) -> EnvRecord {
        let mut r = self.layout.record(self.sample.payload(), j);
        if self.restarted {
            r.flags = FLAG_TRUNCATED | FLAG_RESTARTED;
            r.reward = 0.0;
        }
        r
    }
    /// Whether this block answers a worker restart.
    pub fn restarted(&self) -> bool {
        self.restarted
    }
    /// The underlying iceoryx2 sample (records, then observations; see `layout`).
    pub fn sample(&self) -> &BlockSample {
        &self.sample
    }
}
