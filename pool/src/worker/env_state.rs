//! One env of a worker and what a command does to it: reset, step, autoreset, episode
//! bookkeeping, and where its answer goes in the block ([`EnvOut`], [`BlockOut`]).

use crate::config::AutoresetMode;
use crate::env::Env;
use crate::seeds::SeedSchedule;
use crate::wire::layout::{
    EnvRecord, FLAG_EXTRA_APART, FLAG_FINAL_OBS, FLAG_TERMINATED, FLAG_TRUNCATED,
    write_record_words,
};
use crate::wire::slot_layout::RowWriter;
use crate::wire::{
    EnvFault, KEEP_EPISODE, SLOT_EXTRA_ANY, SLOT_EXTRA_APART, SLOT_EXTRA_UNIFORM, SLOT_FINAL, Serve,
};

/// One env of a worker with its episode bookkeeping (`E = ()` for the envs of an
/// [`crate::EnvBlock`], which owns them).
pub(crate) struct EnvState<E = Box<dyn Env>> {
    pub(crate) env: E,
    /// Global env id.
    pub(crate) global: u64,
    pub(crate) episode: u64,
    pub(crate) seed: u64,
    pub(crate) ret: f64,
    pub(crate) len: u32,
    pub(crate) needs_reset: bool,
}

impl<E> EnvState<E> {
    pub(crate) fn new(env: E, global: u64) -> Self {
        EnvState {
            env,
            global,
            episode: 0,
            seed: 0,
            ret: 0.0,
            len: 0,
            needs_reset: true,
        }
    }

    /// Begin the episode `self.episode` (its seed from the schedule; return and length 0).
    pub(crate) fn begin_episode(&mut self, ctx: &ServeCtx) {
        self.seed = ctx.seeds.seed(self.global, self.episode, ctx.num_envs);
        self.ret = 0.0;
        self.len = 0;
        self.needs_reset = false;
    }

    /// The record's episode bookkeeping.
    pub(crate) fn stamp(&self, rec: &mut EnvRecord) {
        rec.episode = self.episode;
        rec.seed = self.seed;
        rec.episode_return = self.ret;
        rec.episode_length = self.len;
    }

    /// Fail if `value` is an action index out of range (envs of raw action bytes check their
    /// actions themselves).
    pub(crate) fn check_action(&self, value: u64, ctx: &ServeCtx) -> Result<(), EnvFault> {
        if ctx.action_bytes > 0 || value < ctx.num_actions as u64 {
            return Ok(());
        }
        let msg = crate::env::action_out_of_range(value, ctx.num_actions);
        Err(fault(self, "step".into(), msg))
    }

    /// The context of a failed step of this env.
    pub(crate) fn step_context(&self) -> String {
        format!(
            "step (episode {}, seed {}, step {})",
            self.episode, self.seed, self.len
        )
    }
}

/// What [`apply`] needs besides the slot.
pub(crate) struct ServeCtx<'a> {
    pub(crate) seeds: &'a SeedSchedule,
    pub(crate) num_envs: u64,
    pub(crate) autoreset: AutoresetMode,
    pub(crate) num_actions: usize,
    /// `EnvSpec::action_bytes` (0: action indices).
    pub(crate) action_bytes: usize,
    pub(crate) n_info: usize,
}

/// Where one env writes its answer to a command (parts of the block being filled).
pub(crate) struct EnvOut<'a> {
    pub(crate) obs: &'a mut [u8],
    /// SAME_STEP final observation (empty in NEXT_STEP mode).
    pub(crate) fin: &'a mut [u8],
    /// Extra-info room (`EnvSpec::extra_bytes`).
    pub(crate) extra: &'a mut [u8],
    /// The env's extra info, whole; when it does not fit `extra`, the record is flagged
    /// [`FLAG_EXTRA_APART`] and the caller sends these bytes apart.
    pub(crate) info: &'a mut Vec<u8>,
}

pub(crate) fn fault<E>(
    s: &EnvState<E>,
    context: String,
    message: impl std::fmt::Display,
) -> EnvFault {
    EnvFault::new(s.global, context, message)
}

fn do_reset(s: &mut EnvState, obs: &mut [u8], ctx: &ServeCtx) -> Result<(), EnvFault> {
    s.begin_episode(ctx);
    s.env.reset_episode(s.seed, s.episode, obs).map_err(|e| {
        fault(
            s,
            format!("reset (episode {}, seed {})", s.episode, s.seed),
            e,
        )
    })
}

/// Apply one command to one env: [`Serve::Reset`] (`words[0]` = episode index) or [`Serve::Step`]
/// (`words` = the action: an index, or `action_bytes` raw bytes), with autoreset. Writes the
/// observation, the final observation (SAME_STEP, on an episode end) and the extra info into
/// `out`. Returns the env's record. Inlined into the block loop: apart, the native game's env
/// loop takes 3-15% longer (`benchmarks/builds_ab.py`).
#[inline(always)]
pub(crate) fn apply(
    s: &mut EnvState,
    kind: Serve,
    words: &[u64],
    out: EnvOut<'_>,
    ctx: &ServeCtx,
) -> Result<EnvRecord, EnvFault> {
    let EnvOut {
        obs,
        fin,
        extra,
        info,
    } = out;
    let value = words.first().copied().unwrap_or(0);
    let mut rec = EnvRecord::default();
    match kind {
        Serve::Reset if value == KEEP_EPISODE => {
            // Partial reset, env not selected: no state change, same observation again.
            s.env.observe(obs).map_err(|e| {
                let c = format!(
                    "a partial reset (episode {}, seed {}): cannot keep it",
                    s.episode, s.seed
                );
                fault(s, c, e)
            })?;
        }
        Serve::Reset => {
            s.episode = value;
            do_reset(s, obs, ctx)?;
        }
        Serve::Step if s.needs_reset => {
            // NEXT_STEP: this step only resets; the action is ignored.
            s.episode += 1;
            do_reset(s, obs, ctx)?;
        }
        Serve::Step => {
            s.check_action(value, ctx)?;
            let result = if ctx.action_bytes > 0 {
                let bytes = rogue_gym_ipc::words_as_bytes(words);
                s.env
                    .step_bytes(&bytes[..ctx.action_bytes.min(bytes.len())], obs)
            } else {
                s.env.step(value as usize, obs)
            };
            let out = result.map_err(|e| fault(s, s.step_context(), e))?;
            s.ret += out.reward;
            s.len += 1;
            rec.reward = out.reward;
            rec.flags = (u32::from(out.terminated) * FLAG_TERMINATED)
                | (u32::from(out.truncated) * FLAG_TRUNCATED);
        }
    }
    s.stamp(&mut rec);
    s.env.info(&mut rec.info[..ctx.n_info]);
    if rec.flags & (FLAG_TERMINATED | FLAG_TRUNCATED) != 0 {
        match ctx.autoreset {
            AutoresetMode::NextStep => s.needs_reset = true,
            AutoresetMode::SameStep => {
                if fin.len() == obs.len() {
                    fin.copy_from_slice(obs);
                    rec.flags |= FLAG_FINAL_OBS;
                }
                s.episode += 1;
                do_reset(s, obs, ctx)?;
            }
        }
    }
    if !extra.is_empty() {
        // The env has extra info (`EnvSpec::extra_bytes` > 0, so it has room).
        info.clear();
        s.env
            .extra_info(info)
            .map_err(|e| fault(s, "extra info".into(), e))?;
        place_extra(&mut rec, extra, info).map_err(|e| fault(s, "extra info".into(), e))?;
    }
    Ok(rec)
}

/// Put an env's extra info `info` in its room `extra`, or flag the record
/// [`FLAG_EXTRA_APART`] when it does not fit (the worker then sends it beside the block).
pub(crate) fn place_extra(
    rec: &mut EnvRecord,
    extra: &mut [u8],
    info: &[u8],
) -> Result<(), String> {
    let n = info.len();
    rec.extra_len = u32::try_from(n).map_err(|_| format!("{n} bytes of extra info"))?;
    match extra.get_mut(..n) {
        Some(room) => room.copy_from_slice(info),
        None => rec.flags |= FLAG_EXTRA_APART,
    }
    Ok(())
}

/// Where the records of one command's answers go.
pub(crate) enum Rows<'a> {
    /// The block's own records area (the async API's answers).
    Block(&'a mut [u64]),
    /// In place, in the columns of a batch slot, the block's envs from row `first` (whole-batch
    /// calls: the caller reads them there).
    Slot {
        writer: Box<RowWriter>,
        first: usize,
    },
}

/// What the supervisor needs of an answer written into a slot, summed up over the block (it
/// goes in the block's first words: [`crate::wire::SLOT_ANSWER_WORDS`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct AnswerSummary {
    /// `SLOT_*` bits.
    pub(crate) bits: u64,
    /// Envs that wrote extra info.
    pub(crate) extras: usize,
    /// The size of every env's extra info, while all are the same.
    pub(crate) size: usize,
    /// The first 16 bytes of every env's extra info, while all are the same.
    pub(crate) head: [u8; 16],
}

impl AnswerSummary {
    fn add(&mut self, rec: &EnvRecord, extra: &[u8]) {
        if rec.has_final_obs() {
            self.bits |= SLOT_FINAL;
        }
        if rec.extra_apart() {
            self.bits |= SLOT_EXTRA_APART;
        }
        let n = rec.extra_len as usize;
        if n == 0 {
            return;
        }
        let mut head = [0u8; 16];
        let k = n.min(16).min(extra.len());
        head[..k].copy_from_slice(&extra[..k]);
        if self.extras == 0 {
            self.size = n;
            self.head = head;
        } else if self.size != n || self.head != head || rec.extra_apart() {
            self.size = 0;
        }
        self.extras += 1;
        self.bits |= SLOT_EXTRA_ANY;
    }

    /// The block's first words: bits (with [`SLOT_EXTRA_UNIFORM`] when all `envs` wrote one
    /// layout), size, head.
    pub(crate) fn words(&self, envs: usize) -> [u64; crate::wire::SLOT_ANSWER_WORDS] {
        let uniform = self.extras == envs && self.size > 0 && self.bits & SLOT_EXTRA_APART == 0;
        let mut h = [0u64; 2];
        for (w, c) in h.iter_mut().zip(self.head.chunks_exact(8)) {
            *w = u64::from_le_bytes(c.try_into().unwrap_or([0; 8]));
        }
        let bits = self.bits | if uniform { SLOT_EXTRA_UNIFORM } else { 0 };
        [bits, self.size as u64, h[0], h[1]]
    }
}

/// Where one command's answers go: the parts of the worker's block being filled, or of the
/// batch slot it writes in place.
pub(crate) struct BlockOut<'a> {
    pub(crate) records: Rows<'a>,
    /// What an answer in place says of itself.
    pub(crate) summary: AnswerSummary,
    pub(crate) obs: &'a mut [u8],
    pub(crate) final_obs: &'a mut [u8],
    pub(crate) extra: &'a mut [u8],
    pub(crate) obs_bytes: usize,
    pub(crate) final_bytes: usize,
    pub(crate) extra_bytes: usize,
    /// One env's extra info (a buffer reused from env to env).
    pub(crate) info: &'a mut Vec<u8>,
    /// The envs whose info did not fit their room, with that info.
    pub(crate) apart: &'a mut Vec<(u32, Vec<u8>)>,
    /// Where each env writes its observation first when the rows are written with streaming
    /// stores ([`super::streaming`]; one observation long), or empty: envs write their rows.
    pub(crate) stage: &'a mut [u8],
}

impl BlockOut<'_> {
    /// Env `j`'s parts.
    pub(crate) fn env(&mut self, j: usize) -> EnvOut<'_> {
        let (ob, fb, xb) = (self.obs_bytes, self.final_bytes, self.extra_bytes);
        EnvOut {
            obs: if self.stage.is_empty() {
                &mut self.obs[j * ob..(j + 1) * ob]
            } else {
                &mut *self.stage
            },
            fin: &mut self.final_obs[j * fb..(j + 1) * fb],
            extra: &mut self.extra[j * xb..(j + 1) * xb],
            info: &mut *self.info,
        }
    }

    /// Write env `j`'s record; keep its info apart if the record says it did not fit.
    pub(crate) fn finish(&mut self, j: usize, rec: &EnvRecord) {
        if !self.stage.is_empty() {
            let ob = self.obs_bytes;
            super::streaming::copy(&mut self.obs[j * ob..(j + 1) * ob], self.stage);
        }
        match &mut self.records {
            Rows::Block(words) => write_record_words(words, j, rec),
            Rows::Slot { writer, first } => {
                writer.record(*first + j, rec);
                let xb = self.extra_bytes;
                self.summary.add(rec, &self.extra[j * xb..(j + 1) * xb]);
            }
        }
        if rec.extra_apart() {
            self.apart.push((j as u32, std::mem::take(self.info)));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinds::test_env::TestEnv;

    fn env_state() -> EnvState {
        let env =
            TestEnv::from_json(&serde_json::json!({"obs_shape": [4], "max_steps": 3})).unwrap();
        EnvState::new(Box::new(env), 5)
    }

    fn go(
        s: &mut EnvState,
        kind: Serve,
        value: u64,
        obs: &mut [u8],
        fin: &mut [u8],
        c: &ServeCtx,
    ) -> Result<EnvRecord, EnvFault> {
        let extra: &mut [u8] = &mut [];
        let info = &mut Vec::new();
        apply(
            s,
            kind,
            &[value],
            EnvOut {
                obs,
                fin,
                extra,
                info,
            },
            c,
        )
    }

    fn ctx(seeds: &SeedSchedule, autoreset: AutoresetMode) -> ServeCtx<'_> {
        ServeCtx {
            seeds,
            num_envs: 8,
            autoreset,
            num_actions: 5,
            action_bytes: 0,
            n_info: 2,
        }
    }

    #[test]
    fn next_step_autoreset_ignores_action_and_keeps_last_reward() {
        let seeds = SeedSchedule::from_base(1);
        let c = ctx(&seeds, AutoresetMode::NextStep);
        let mut s = env_state();
        let (mut obs, mut fin) = ([0u8; 4], [0u8; 0]);
        let r = go(&mut s, Serve::Reset, 0, &mut obs, &mut fin, &c).unwrap();
        assert_eq!((r.episode, r.seed, r.flags), (0, seeds.seed(5, 0, 8), 0));
        let mut total = 0.0;
        for t in 1..=3 {
            let r = go(&mut s, Serve::Step, 1, &mut obs, &mut fin, &c).unwrap();
            total += r.reward;
            assert_eq!(r.episode_length, t);
            if r.terminated() {
                break;
            }
            assert_eq!(r.truncated(), t == 3, "max_steps 3 truncates at step 3");
        }
        // The episode ended: its last reward was reported; the next step only resets.
        assert_eq!(s.ret, total);
        let r = go(&mut s, Serve::Step, 4, &mut obs, &mut fin, &c).unwrap();
        assert_eq!(r.reward, 0.0);
        assert!(!r.terminated() && !r.truncated());
        assert_eq!(
            (r.episode, r.seed, r.episode_length),
            (1, seeds.seed(5, 1, 8), 0)
        );
        let mut fresh = [0u8; 4];
        let mut e = TestEnv::from_json(&serde_json::json!({"obs_shape": [4]})).unwrap();
        e.reset(seeds.seed(5, 1, 8), &mut fresh).unwrap();
        assert_eq!(obs, fresh, "the reset obs is returned");
    }

    #[test]
    fn same_step_autoreset_returns_reset_obs_and_final_obs() {
        let seeds = SeedSchedule::from_base(1);
        let c = ctx(&seeds, AutoresetMode::SameStep);
        let mut s = env_state();
        let (mut obs, mut fin) = ([0u8; 4], [0u8; 4]);
        go(&mut s, Serve::Reset, 0, &mut obs, &mut fin, &c).unwrap();
        // Replay the same episode on a bare env to know the final obs.
        let mut bare =
            TestEnv::from_json(&serde_json::json!({"obs_shape": [4], "max_steps": 3})).unwrap();
        let mut bobs = [0u8; 4];
        bare.reset(seeds.seed(5, 0, 8), &mut bobs).unwrap();
        loop {
            let o = bare.step(2, &mut bobs).unwrap();
            let r = go(&mut s, Serve::Step, 2, &mut obs, &mut fin, &c).unwrap();
            assert_eq!(r.reward, o.reward, "the final reward is kept");
            if o.terminated || o.truncated {
                assert_eq!((r.terminated(), r.truncated()), (o.terminated, o.truncated));
                assert!(r.has_final_obs());
                assert_eq!(fin, bobs, "final obs kept separately");
                assert_eq!(r.episode, 0, "the record describes the finished episode");
                bare.reset(seeds.seed(5, 1, 8), &mut bobs).unwrap();
                assert_eq!(obs, bobs, "obs is the next episode's first");
                assert_eq!(s.episode, 1);
                break;
            }
            assert_eq!(obs, bobs);
        }
        // The next step acts normally in the new episode.
        let r = go(&mut s, Serve::Step, 0, &mut obs, &mut fin, &c).unwrap();
        assert_eq!((r.episode, r.episode_length), (1, 1));
    }

    #[test]
    fn bad_action_is_an_error_not_a_panic() {
        let seeds = SeedSchedule::from_base(1);
        let c = ctx(&seeds, AutoresetMode::NextStep);
        let mut s = env_state();
        let (mut obs, mut fin) = ([0u8; 4], [0u8; 0]);
        go(&mut s, Serve::Reset, 0, &mut obs, &mut fin, &c).unwrap();
        let e = go(&mut s, Serve::Step, 99, &mut obs, &mut fin, &c).unwrap_err();
        assert_eq!(e.env, 5);
        assert!(e.message.contains("action 99"), "{}", e.message);
    }
}
