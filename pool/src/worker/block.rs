//! A worker's block of envs hosted as one [`EnvBlock`] (a vector env): one call resets or
//! steps every env of the block, while the worker keeps each env's episode bookkeeping exactly
//! as [`super::env_state::apply`] does for single envs, so that records read the same either way.

use std::ops::Range;

use crate::config::AutoresetMode;
use crate::env::{EnvBlock, EnvSpec, StepOutcome};
use crate::wire::record::{EnvRecord, FLAG_FINAL_OBS, FLAG_TERMINATED, FLAG_TRUNCATED};
use crate::wire::{EnvFault, KEEP_EPISODE, Serve};

use super::block_out::{BlockOut, place_extra};
use super::env_state::{EnvState, ServeCtx, fault};

/// An [`EnvBlock`] with the bookkeeping of its envs and the buffers of its calls.
pub(crate) struct BlockHost {
    block: Box<dyn EnvBlock>,
    /// Each env's episode bookkeeping (the block owns the envs themselves).
    books: Vec<EnvState<()>>,
    mask: Vec<bool>,
    seeds: Vec<u64>,
    episodes: Vec<u64>,
    outcomes: Vec<StepOutcome>,
}

impl BlockHost {
    /// Host `block`, the envs `globals` of the pool.
    pub(crate) fn new(block: Box<dyn EnvBlock>, globals: Range<u64>) -> Self {
        let books: Vec<EnvState<()>> = globals.map(|g| EnvState::new((), g)).collect();
        let n = books.len();
        BlockHost {
            block,
            books,
            mask: vec![false; n],
            seeds: vec![0; n],
            episodes: vec![0; n],
            outcomes: vec![StepOutcome::default(); n],
        }
    }

    /// Envs of the block.
    pub(crate) fn len(&self) -> usize {
        self.books.len()
    }

    /// Each env's episode bookkeeping.
    pub(crate) fn books(&self) -> &[EnvState<()>] {
        &self.books
    }

    /// The envs' spec.
    pub(crate) fn spec(&self) -> EnvSpec {
        self.block.spec()
    }

    /// Answer a call for env `j` of the block.
    pub(crate) fn call(
        &mut self,
        j: usize,
        request: &[u8],
    ) -> Result<Vec<u8>, crate::env::EnvError> {
        self.block.call(j, request)
    }

    /// Answer a whole request of calls at once (see [`EnvBlock::calls`]).
    pub(crate) fn calls(
        &mut self,
        requests: &[(usize, &[u8])],
    ) -> Result<Vec<Vec<u8>>, crate::env::EnvError> {
        self.block.calls(requests)
    }

    /// The fault of a command for some of the block's envs only: a vector env steps all its
    /// envs at once (the supervisor refuses such commands before they are sent).
    pub(crate) fn whole_block_only(&self) -> EnvFault {
        self.block_fault(
            "a step",
            "a vector env per worker steps all its envs at once: send() must cover whole worker blocks",
        )
    }

    /// A failure of the block as a whole, blamed on its first env.
    fn block_fault(&self, context: &str, e: impl std::fmt::Display) -> EnvFault {
        fault(
            &self.books[0],
            format!("{context} of its worker's vector env"),
            e,
        )
    }

    /// Answer one command ([`Serve::Reset`]: an episode index or [`KEEP_EPISODE`] per env;
    /// [`Serve::Step`]: an action per env) for the whole block, records and extra info
    /// included.
    pub(crate) fn serve(
        &mut self,
        kind: Serve,
        payload: &[u64],
        out: &mut BlockOut<'_>,
        ctx: &ServeCtx,
    ) -> Result<(), EnvFault> {
        let n = self.books.len();
        match kind {
            Serve::Reset => {
                for (j, s) in self.books.iter_mut().enumerate() {
                    let value = payload[j];
                    self.mask[j] = value != KEEP_EPISODE;
                    if self.mask[j] {
                        s.episode = value;
                        s.begin_episode(ctx);
                    }
                    self.seeds[j] = s.seed;
                    self.episodes[j] = s.episode;
                }
                self.block
                    .reset(&self.mask, &self.seeds, &self.episodes, out.obs)
                    .map_err(|e| self.block_fault("reset", e))?;
            }
            Serve::Step => {
                for (j, s) in self.books.iter_mut().enumerate() {
                    // NEXT_STEP: an env whose episode ended resets on this step (the block
                    // does it) and its action is ignored.
                    self.mask[j] = s.needs_reset;
                    if s.needs_reset {
                        s.episode += 1;
                        s.begin_episode(ctx);
                    }
                }
                self.block
                    .step(payload, out.obs, out.final_obs, &mut self.outcomes)
                    .map_err(|e| self.block_fault("a step", e))?;
                for (j, s) in self.books.iter_mut().enumerate() {
                    if !self.mask[j] {
                        let o = self.outcomes[j];
                        s.ret += o.reward;
                        s.len += 1;
                        s.needs_reset = o.terminated || o.truncated;
                    }
                }
            }
        }
        for j in 0..n {
            let mut rec = EnvRecord::default();
            if kind == Serve::Step && !self.mask[j] {
                let o = self.outcomes[j];
                rec.reward = o.reward;
                rec.flags = (u32::from(o.terminated) * FLAG_TERMINATED)
                    | (u32::from(o.truncated) * FLAG_TRUNCATED);
            }
            self.books[j].stamp(&mut rec);
            let ended = rec.flags & (FLAG_TERMINATED | FLAG_TRUNCATED) != 0;
            if ended && ctx.autoreset == AutoresetMode::SameStep {
                // The block has reset the env already; the record describes the finished
                // episode, the books begin the next.
                if out.final_bytes > 0 {
                    rec.flags |= FLAG_FINAL_OBS;
                }
                let s = &mut self.books[j];
                s.episode += 1;
                s.begin_episode(ctx);
            }
            if out.extra_bytes > 0 {
                out.info.clear();
                self.block
                    .extra_info(j, out.info)
                    .map_err(|e| fault(&self.books[j], "extra info".into(), e))?;
                let xb = out.extra_bytes;
                place_extra(&mut rec, &mut out.extra[j * xb..(j + 1) * xb], out.info)
                    .map_err(|e| fault(&self.books[j], "extra info".into(), e))?;
            }
            out.finish(j, &rec);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::AutoresetMode;
    use crate::env::{Env, EnvError};
    use crate::kinds::test_env::TestEnv;
    use crate::seeds::SeedSchedule;
    use crate::wire::slot_layout::{SlotLayout, SlotRows};
    use crate::worker::block_out::{EnvOut, Scratch};
    use crate::worker::env_state::apply;

    const N: usize = 3;
    const OB: usize = 4;
    const NUM_ENVS: u64 = 8;
    const FIRST: u64 = 2;

    fn test_env() -> TestEnv {
        TestEnv::from_json(&serde_json::json!({"obs_shape": [OB], "max_steps": 3})).unwrap()
    }

    /// A block of [`TestEnv`]s that autoresets `NEXT_STEP` or `SAME_STEP` and, where a
    /// gymnasium vector env would continue an env's generator, reseeds from the schedule as the
    /// worker's single envs do, so that both paths must give the same records.
    struct Naive {
        envs: Vec<TestEnv>,
        ended: Vec<bool>,
        episode: Vec<u64>,
        seeds: SeedSchedule,
    }

    impl Naive {
        fn next_episode(&mut self, j: usize, row: &mut [u8]) -> Result<(), EnvError> {
            self.episode[j] += 1;
            let seed = self.seeds.seed(FIRST + j as u64, self.episode[j], NUM_ENVS);
            self.envs[j].reset(seed, row)
        }
    }

    impl EnvBlock for Naive {
        fn spec(&self) -> EnvSpec {
            self.envs[0].spec()
        }
        fn reset(
            &mut self,
            mask: &[bool],
            seeds: &[u64],
            episodes: &[u64],
            obs: &mut [u8],
        ) -> Result<(), EnvError> {
            for (j, row) in obs.chunks_exact_mut(OB).enumerate() {
                if mask[j] {
                    self.episode[j] = episodes[j];
                    self.ended[j] = false;
                    self.envs[j].reset(seeds[j], row)?;
                } else {
                    self.envs[j].observe(row)?;
                }
            }
            Ok(())
        }
        fn step(
            &mut self,
            actions: &[u64],
            obs: &mut [u8],
            fin: &mut [u8],
            out: &mut [StepOutcome],
        ) -> Result<(), EnvError> {
            for (j, row) in obs.chunks_exact_mut(OB).enumerate() {
                if self.ended[j] {
                    self.next_episode(j, row)?;
                    out[j] = StepOutcome::default();
                    self.ended[j] = false;
                    continue;
                }
                out[j] = self.envs[j].step(actions[j] as usize, row)?;
                self.ended[j] = out[j].terminated || out[j].truncated;
                if self.ended[j] && !fin.is_empty() {
                    fin[j * OB..(j + 1) * OB].copy_from_slice(row);
                    self.next_episode(j, row)?;
                    self.ended[j] = false;
                }
            }
            Ok(())
        }
    }

    fn ctx(seeds: &SeedSchedule, autoreset: AutoresetMode) -> ServeCtx<'_> {
        ServeCtx {
            seeds,
            num_envs: NUM_ENVS,
            autoreset,
            action_bytes: 0,
            n_info: 0,
        }
    }

    fn host(seeds: &SeedSchedule) -> BlockHost {
        let naive = Naive {
            envs: (0..N).map(|_| test_env()).collect(),
            ended: vec![false; N],
            episode: vec![0; N],
            seeds: seeds.clone(),
        };
        BlockHost::new(Box::new(naive), FIRST..FIRST + N as u64)
    }

    /// 64 bytes of 64-byte aligned memory (a slot is made of them).
    #[derive(Clone, Copy)]
    #[repr(align(64))]
    struct Line(#[allow(dead_code)] [u8; 64]);

    /// Serve one command into a slot of a pool of `FIRST + N` envs; the slot's memory and rows.
    fn serve(
        host: &mut BlockHost,
        kind: Serve,
        payload: &[u64],
        ctx: &ServeCtx,
    ) -> Result<(Vec<Line>, SlotRows), EnvFault> {
        let layout = SlotLayout {
            num_envs: FIRST as usize + N,
            obs_bytes: OB,
            n_info: 0,
            final_obs: ctx.autoreset == AutoresetMode::SameStep,
            extra_bytes: 0,
        };
        let mut slot = vec![Line([0; 64]); layout.bytes().div_ceil(64)];
        // SAFETY: a slot of this layout, 64-byte aligned, this test's alone.
        let rows = unsafe { layout.rows(slot.as_mut_ptr().cast()) };
        let mut scratch = Scratch::default();
        // SAFETY: as above.
        let mut out = unsafe { BlockOut::in_slot(rows, FIRST as usize, N, &mut scratch) };
        host.serve(kind, payload, &mut out, ctx)?;
        Ok((slot, rows))
    }

    #[test]
    fn a_block_keeps_the_same_books_as_single_envs() {
        for mode in [AutoresetMode::NextStep, AutoresetMode::SameStep] {
            same_books(mode);
        }
    }

    fn same_books(mode: AutoresetMode) {
        let seeds = SeedSchedule::from_base(9);
        let ctx = ctx(&seeds, mode);
        let mut host = host(&seeds);
        let mut slots: Vec<EnvState> = (0..N as u64)
            .map(|j| EnvState::new(Box::new(test_env()) as Box<dyn Env>, FIRST + j))
            .collect();
        let mut commands = vec![(Serve::Reset, vec![0u64; N])];
        commands.extend(
            (0..12u64).map(|t| (Serve::Step, (0..N as u64).map(|j| (t + j) % 5).collect())),
        );
        commands.push((Serve::Reset, vec![KEEP_EPISODE, 4, KEEP_EPISODE]));
        commands.push((Serve::Step, vec![1, 2, 3]));
        let mut ends = 0;
        for (kind, payload) in commands {
            let (_slot, rows) = serve(&mut host, kind, &payload, &ctx).unwrap();
            for (j, s) in slots.iter_mut().enumerate() {
                let (mut obs, mut fin) = ([0u8; OB], [0u8; OB]);
                let fb = if mode == AutoresetMode::SameStep {
                    OB
                } else {
                    0
                };
                let env_out = EnvOut {
                    obs: &mut obs,
                    fin: &mut fin[..fb],
                    extra: &mut [],
                    info: &mut Vec::new(),
                };
                let want = apply(s, kind, &payload[j..j + 1], env_out, &ctx).unwrap();
                ends += usize::from(want.truncated() || want.terminated());
                let e = FIRST as usize + j;
                assert_eq!(rows.read(e), want, "{mode:?}: command {kind:?}, env {j}");
                // SAFETY: the slot is alive (`_slot`) and no one writes it now.
                let (got, got_fin) =
                    unsafe { (rows.obs_rows(e..e + 1), rows.final_rows(e..e + 1)) };
                assert_eq!(got, &obs);
                if want.has_final_obs() {
                    assert_eq!(got_fin, &fin);
                }
            }
        }
        assert!(ends >= N * 3, "the run crosses episode ends ({ends})");
    }
}
