//! The [`Env`] trait hosted by the pool, and what describes an env from outside ([`EnvSpec`]).

/// Element type of an observation tensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Dtype {
    /// `u8`, one byte per element.
    U8,
    /// `f32`, four bytes per element (native endianness).
    F32,
}

impl Dtype {
    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            Dtype::U8 => 1,
            Dtype::F32 => 4,
        }
    }
    /// The numpy name of the type (`"uint8"` or `"float32"`).
    pub fn numpy_name(self) -> &'static str {
        match self {
            Dtype::U8 => "uint8",
            Dtype::F32 => "float32",
        }
    }
}

/// Most env-defined info values per env (see [`EnvSpec::info_names`]).
pub const MAX_INFO: usize = 8;

/// What an env looks like from outside: observation shape and type, action count, and the names
/// of its small fixed array of info values.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EnvSpec {
    /// Observation shape, e.g. `[17, 16, 32]`.
    pub obs_shape: Vec<usize>,
    /// Observation element type.
    pub dtype: Dtype,
    /// Number of discrete actions; valid actions are `0..num_actions`.
    pub num_actions: usize,
    /// Names of the env's info values (at most [`MAX_INFO`]), e.g. `["floor", "gold", "hp"]`.
    pub info_names: Vec<String>,
    /// `0`: actions are indices `0..num_actions` ([`Env::step`]). `n > 0`: each action is `n`
    /// raw bytes that the env decodes and checks itself ([`Env::step_bytes`]); `num_actions` is
    /// then unused.
    #[serde(default)]
    pub action_bytes: usize,
    /// Room per env and step for variable-size extra info ([`Env::extra_info`]) in the
    /// worker's block, in bytes; longer info goes through a side file. `0`: the env has none.
    #[serde(default)]
    pub extra_bytes: usize,
    /// The info values of [`EnvSpec::info_names`] that are flags (0 or 1): a binding hands
    /// them out as `bool`s (the caller checks their bytes, `SlotRows::check_flags`), the
    /// others as integers.
    #[serde(default)]
    pub flag_infos: Vec<String>,
}

impl EnvSpec {
    /// Number of elements of one observation.
    pub fn obs_len(&self) -> usize {
        self.obs_shape.iter().product()
    }
    /// Bytes of one observation.
    pub fn obs_bytes(&self) -> usize {
        self.obs_len() * self.dtype.size()
    }
    /// Command words (`u64`) one env's action takes on the wire.
    pub fn action_words(&self) -> usize {
        self.action_bytes.div_ceil(8).max(1)
    }
    /// The rows of the `info_*` columns of the [`EnvSpec::flag_infos`].
    pub fn flag_info_rows(&self) -> Vec<usize> {
        (self.info_names.iter().enumerate())
            .filter(|(_, n)| self.flag_infos.contains(n))
            .map(|(j, _)| j)
            .collect()
    }
    /// Check the spec is usable by the pool.
    pub fn validate(&self) -> Result<(), EnvError> {
        if self.obs_len() == 0 {
            return Err(EnvError::new(format!(
                "observation shape {:?} is empty",
                self.obs_shape
            )));
        }
        if self.num_actions == 0 && self.action_bytes == 0 {
            return Err(EnvError::new("the env declares 0 actions"));
        }
        if let Some(f) = self
            .flag_infos
            .iter()
            .find(|f| !self.info_names.contains(f))
        {
            return Err(EnvError::new(format!(
                "the flag info {f:?} is not one of the info values {:?}",
                self.info_names
            )));
        }
        if self.info_names.len() > MAX_INFO {
            return Err(EnvError::new(format!(
                "the env declares {} info values; at most {MAX_INFO} are supported",
                self.info_names.len()
            )));
        }
        Ok(())
    }
}

/// Result of one env step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepOutcome {
    /// Reward of the step.
    pub reward: f64,
    /// The episode ended by the game's rules (death, win).
    pub terminated: bool,
    /// The episode was cut (step limit).
    pub truncated: bool,
}

/// An error of an env (bad config, bad action, encoder failure). A message for humans.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct EnvError(pub String);

impl EnvError {
    /// Build an error from a message.
    pub fn new(msg: impl Into<String>) -> Self {
        EnvError(msg.into())
    }
}

/// An environment the pool can host. Observations are written in place into the caller's byte
/// slice (in a worker: straight into the shared-memory sample), which is exactly
/// [`EnvSpec::obs_bytes`] long and, for `f32` observations, 4-byte aligned. `Send`: a worker
/// may run each of its envs on a thread of its own (`WorkerConfig::env_threads`).
pub trait Env: Send {
    /// The env's spec; must not change over the env's life.
    fn spec(&self) -> EnvSpec;
    /// Start a new episode from `seed` and write its first observation.
    fn reset(&mut self, seed: u64, obs: &mut [u8]) -> Result<(), EnvError>;
    /// Start episode `episode` (0, 1, ...: the `e` of the seed schedule) from `seed`. The
    /// default ignores `episode` and calls [`Env::reset`]; hosted gymnasium envs override it to
    /// seed only episode 0 and let later episodes continue the env's own generator.
    fn reset_episode(&mut self, seed: u64, episode: u64, obs: &mut [u8]) -> Result<(), EnvError> {
        let _ = episode;
        self.reset(seed, obs)
    }
    /// Apply `action` (already checked to be `< num_actions`) and write the new observation.
    fn step(&mut self, action: usize, obs: &mut [u8]) -> Result<StepOutcome, EnvError>;
    /// Apply an action given as [`EnvSpec::action_bytes`] raw bytes (envs whose spec says so);
    /// the env checks it. The default says the env takes action indices.
    fn step_bytes(&mut self, action: &[u8], obs: &mut [u8]) -> Result<StepOutcome, EnvError> {
        let _ = (action, obs);
        Err(EnvError::new(
            "this env kind takes action indices, not raw action bytes",
        ))
    }
    /// Take the part of the next step's action that has no fixed size, just before that step
    /// (bytes whose meaning is the env's business; hosted envs: the pickled values of an
    /// action space's leaves of no fixed size). The default says the env takes none.
    fn set_action_extra(&mut self, extra: &[u8]) -> Result<(), EnvError> {
        let _ = extra;
        Err(EnvError::new(
            "this env kind takes actions of a fixed size only (no action extras)",
        ))
    }
    /// Append the variable-size extra info of the last command (its `reset`, its `step`, or
    /// a step and its autoreset) to `out`; append nothing for none. Called once after each
    /// command, only for specs with [`EnvSpec::extra_bytes`] > 0; what the bytes mean is the
    /// env's business (hosted envs: their info dicts as typed rows or pickles). Info longer
    /// than [`EnvSpec::extra_bytes`] is not an error: the worker carries it apart.
    fn extra_info(&mut self, out: &mut Vec<u8>) -> Result<(), EnvError> {
        let _ = out;
        Ok(())
    }
    /// Write the env's info values (as many as [`EnvSpec::info_names`]) into `out`.
    fn info(&self, out: &mut [f64]) {
        let _ = out;
    }
    /// Answer a call from the caller, off the hot path (attribute reads and writes, method
    /// calls, renders): `request` and the reply are bytes whose meaning is the env's business
    /// (hosted envs: pickles). The default says the env takes no calls.
    fn call(&mut self, request: &[u8]) -> Result<Vec<u8>, EnvError> {
        let _ = request;
        Err(EnvError::new("this env kind takes no calls"))
    }
    /// Re-write the current observation (the bytes the last `reset`/`step` wrote) without
    /// changing any state. The pool's partial reset ([`crate::Pool::send_reset`] with a mask)
    /// calls it for the envs it does *not* reset, so that their current observation lands in
    /// the new batch.
    /// The default says the env cannot: such envs support full resets only.
    fn observe(&self, obs: &mut [u8]) -> Result<(), EnvError> {
        let _ = obs;
        Err(EnvError::new(
            "this env kind cannot re-render its observation (Env::observe), which partial resets need",
        ))
    }
}

/// A worker's whole block of envs behind one object: an env kind that hosts a vector env (one
/// per worker, e.g. ale-py's C++ `AtariVectorEnv`) and steps every env of the block in one
/// call. The worker keeps each env's episode bookkeeping (episode, seed, return, length) as it
/// does for single [`Env`]s; the block resets and steps, and must autoreset as the pool does
/// (`NEXT_STEP`: the step after an env's episode ended resets it and ignores its action;
/// `SAME_STEP`: the step that ends an episode resets the env and keeps its final observation).
/// Observations are written in place: row `j` of `obs` (each [`EnvSpec::obs_bytes`] long) is
/// env `j`'s.
pub trait EnvBlock {
    /// The spec of every env of the block; must not change over the block's life.
    fn spec(&self) -> EnvSpec;
    /// Reset the envs with `mask[j]` set, env `j` for its episode `episodes[j]` from
    /// `seeds[j]` (as [`Env::reset_episode`] reads them), and write every env's observation:
    /// the others' current one again.
    fn reset(
        &mut self,
        mask: &[bool],
        seeds: &[u64],
        episodes: &[u64],
        obs: &mut [u8],
    ) -> Result<(), EnvError>;
    /// Step every env: env `j`'s action is `actions[j * w..(j + 1) * w]` (`w` =
    /// [`EnvSpec::action_words`]: an index already checked against `num_actions`, or
    /// [`EnvSpec::action_bytes`] raw bytes), its outcome goes to `out[j]`. In `SAME_STEP`
    /// mode (`fin` is as long as `obs`, else empty) an env whose episode ends writes its first
    /// observation of the next episode to `obs` and its final one to its row of `fin`.
    fn step(
        &mut self,
        actions: &[u64],
        obs: &mut [u8],
        fin: &mut [u8],
        out: &mut [StepOutcome],
    ) -> Result<(), EnvError>;
    /// Append env `j`'s extra info of the last command to `out` (see [`Env::extra_info`]).
    fn extra_info(&mut self, j: usize, out: &mut Vec<u8>) -> Result<(), EnvError> {
        let _ = (j, out);
        Ok(())
    }
    /// Answer a call for env `j` (see [`Env::call`]).
    fn call(&mut self, j: usize, request: &[u8]) -> Result<Vec<u8>, EnvError> {
        let _ = (j, request);
        Err(EnvError::new("this env kind takes no calls"))
    }
    /// Answer the calls of one request, `(j, request)` for env `j` each: one reply each, in
    /// order. The default answers them one by one ([`EnvBlock::call`]); a block whose envs act
    /// together (a vector env) answers them at once, so that an operation asked of every env
    /// runs once, not once per env.
    fn calls(&mut self, requests: &[(usize, &[u8])]) -> Result<Vec<Vec<u8>>, EnvError> {
        requests.iter().map(|&(j, r)| self.call(j, r)).collect()
    }
}

/// View an f32 observation buffer as `&mut [f32]`; errors if misaligned or of odd length.
pub fn bytes_as_f32_mut(obs: &mut [u8]) -> Result<&mut [f32], EnvError> {
    // SAFETY: every bit pattern is a valid f32; align_to_mut handles alignment.
    let (pre, mid, post) = unsafe { obs.align_to_mut::<f32>() };
    if !pre.is_empty() || !post.is_empty() {
        return Err(EnvError::new(
            "f32 observation buffer is not 4-byte aligned or not a multiple of 4 bytes",
        ));
    }
    Ok(mid)
}

/// The words for an action index outside `0..num_actions`, written once: the pool's checks
/// (and the Python front's, which words it the same) say it so.
pub fn action_out_of_range(value: impl std::fmt::Display, num_actions: usize) -> String {
    format!(
        "action {value} is out of range; valid actions are 0 to {} (range({num_actions}))",
        num_actions.saturating_sub(1)
    )
}
