//! What a call hands back: its rows ([`Received`]), and those rows copied out
//! ([`BatchOutput`]).

use crate::wire::record::EnvRecord;

/// Per-env arrays of one batch, copied out of a slot ([`crate::Pool::read_rows`]). Row `r`
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

/// What a call hands back, sync or async: envs' rows, first sent first. A whole-batch call
/// (step, reset, partial reset) hands back every env in env order, as a view of the batch slot
/// the workers wrote; a `recv` the first envs ready, as a view where they are one run of envs
/// in one slot and the caller asked for views ([`crate::Pool::set_async_views`]), else
/// gathered (copied out).
#[derive(Debug, Default)]
pub struct Received {
    /// The envs of the rows.
    pub env_ids: Vec<usize>,
    /// Gathered rows: their records (restart flags applied); empty for a view.
    pub records: Vec<EnvRecord>,
    /// Gathered rows: their observations, `rows x obs_bytes` bytes; empty for a view.
    pub obs: Vec<u8>,
    /// The rows' extra info ([`crate::Env::extra_info`]: hosted envs' infos).
    pub extras: SlotExtras,
    /// The envs of rows whose worker was replaced by plan ([`crate::Pool::recycled_envs`]).
    pub recycled: Vec<usize>,
    /// Some row answers a restart of its worker (its record says `restarted`; a view's
    /// `restarted` column is valid for every row then, and only then).
    pub restarted: bool,
    /// (SAME_STEP) some row has a final observation in its slot's final area.
    pub final_obs: bool,
    /// `Some((slot, first))`: the rows are envs `first..first + rows` in order, in batch slot
    /// `slot`, where the caller reads them (observations, columns, final observations and
    /// extra room) until those envs' next answer but one. `None`: the rows are gathered.
    pub view: Option<(usize, usize)>,
}

impl Received {
    /// The slot of a view (every whole-batch call's result is one).
    pub fn slot(&self) -> Option<usize> {
        self.view.map(|(slot, _)| slot)
    }

    /// Write gathered rows' records into `columns`, row `r` at index `r` (a binding's `recv`
    /// columns: the layout of a slot's columns, rows in receive order).
    pub fn write_columns(&self, columns: &crate::SlotRows) {
        for (r, rec) in self.records.iter().enumerate() {
            columns.record(r, rec);
        }
    }
}

/// The extra info of a call's rows ([`crate::Env::extra_info`]: hosted envs' infos).
#[derive(Debug, Clone, Default, PartialEq)]
pub enum SlotExtras {
    /// No env wrote any.
    #[default]
    None,
    /// (A view) every row's env wrote this many bytes of one layout (the same first 16
    /// bytes), each in its room of the slot's extra area: read them there.
    Uniform(usize),
    /// Some envs wrote some, not all of one layout (or the rows are gathered): `(row, bytes)`
    /// in row order, of those that did.
    Rows(Vec<(usize, Vec<u8>)>),
}
