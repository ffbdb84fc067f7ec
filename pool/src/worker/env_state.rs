//! One env of a worker and what a command does to it ([`apply`]): reset, step, autoreset and
//! the episode bookkeeping. Where its answer goes is [`super::block_out`].

use super::block_out::{EnvOut, place_extra};
use crate::config::AutoresetMode;
use crate::env::Env;
use crate::seeds::SeedSchedule;
use crate::wire::record::{EnvRecord, FLAG_FINAL_OBS, FLAG_TERMINATED, FLAG_TRUNCATED};
use crate::wire::{EnvFault, KEEP_EPISODE, Serve};

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
    /// `EnvSpec::action_bytes` (0: action indices).
    pub(crate) action_bytes: usize,
    pub(crate) n_info: usize,
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
            // The action was checked on the caller's side (`Actions::check`): an index in
            // range, or `action_bytes` bytes.
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
}
