//! The commands the supervisor sends its workers: resets and steps (each env's rows into the
//! slot the command names for it: [`Target`]), the reset that brings a replaced worker's envs
//! back, paced as the machine's booking says.

use super::Supervisor;
use super::actions::Actions;
use super::link::Target;
use crate::error::{FailureCause, PoolError};
use crate::wire::books::next_episode;
use crate::wire::command::next_seq;
use crate::wire::{Command, KEEP_EPISODE, Op, calls};

/// The actions a step command carries, one per env of the worker's block.
#[derive(Clone, Copy)]
pub(super) enum StepActions<'a> {
    /// The block's rows of the caller's actions (a whole-batch step).
    Rows(Actions<'a>),
    /// Action words, `action_words` per env (the async API's staged actions).
    Words(&'a [u64]),
}

impl StepActions<'_> {
    /// Write them into a command's payload `p` (`aw` words per env; `ab` bytes per raw action).
    pub(super) fn write(self, p: &mut [u64], aw: usize, ab: usize) {
        match self {
            StepActions::Words(w) => p.copy_from_slice(w),
            StepActions::Rows(Actions::Indices(a)) => {
                for (d, a) in p.iter_mut().zip(a) {
                    *d = *a as u64;
                }
            }
            StepActions::Rows(Actions::Bytes(b)) => {
                for (j, w) in p.chunks_mut(aw).enumerate() {
                    w.fill(0);
                    rogue_gym_ipc::words_as_bytes_mut(w)[..ab]
                        .copy_from_slice(&b[j * ab..(j + 1) * ab]);
                }
            }
        }
    }
}

impl Supervisor {
    /// A command to the workers, paced as the machine's booking says (`machine.rs`).
    fn command(&mut self, op: Op, target: u32) -> Command {
        Command {
            pace: self.machine.worker_pace(self.async_api.on),
            ..Command::new(op, target)
        }
    }

    /// Write the action extras staged for worker `k`'s next step to its file; whether there
    /// were any ([`Command::action_extras`]).
    fn write_action_extras(&mut self, k: usize) -> Result<bool, PoolError> {
        let Some(extras) = self.workers[k].action_extras.take() else {
            return Ok(false);
        };
        let path = calls::action_extras_path(&self.id, k, self.workers[k].generation);
        calls::write(&path, &extras).map_err(PoolError::Io)?;
        Ok(true)
    }

    /// Reset command to worker `k`, its envs' rows to `target`; with `mask` (the whole
    /// pool's), envs whose entry is false get [`KEEP_EPISODE`] (keep state, re-write the
    /// current observation).
    pub(super) fn send_reset(
        &mut self,
        k: usize,
        target: Target<'_>,
        mask: Option<&[bool]>,
    ) -> Result<(), PoolError> {
        let range = self.env_range(k);
        self.workers[k].action_extras = None; // staged for a step that a reset replaces
        // A replaced worker resets all its envs; in a partial reset they say why.
        let cut = std::mem::take(&mut self.workers[k].cut);
        self.workers[k].restarted |= cut && mask.is_some();
        let mask = mask.filter(|_| !cut);
        let mut eps = Vec::with_capacity(2 * range.len());
        for i in range {
            if mask.is_some_and(|m| !m[i]) {
                eps.push(KEEP_EPISODE);
                continue;
            }
            let Some((e, _)) = self.book(k, i) else {
                eps.push(0);
                continue;
            };
            let Some(next) = next_episode(e) else {
                // The worker wrote an episode index no env reaches: its envs' place in the
                // seed schedule is lost, so they start over from episode 0.
                self.workers[k].first_episodes = true;
                let what = format!("env {i}'s episode index {e} in the episode books");
                return self.lose(k, FailureCause::Corrupt(what), true);
            };
            eps.push(next);
        }
        let (slot, each) = target.words();
        eps.extend_from_slice(each.unwrap_or(&[]));
        let cmd = Command {
            reload_seeds: std::mem::take(&mut self.reload_seeds[k]),
            subset: each.is_some(),
            ..self.command(Op::Reset, slot)
        };
        let s = &mut self.workers[k];
        s.seq = next_seq(s.seq, s.delivered);
        s.ports
            .send_cmd(s.seq, cmd.encode(), eps.len(), |p| p.copy_from_slice(&eps))?;
        s.pending_now();
        Ok(())
    }

    /// The reset that brings worker `k`'s envs back after it was replaced, each env into its
    /// slot ([`super::async_envs::AsyncEnvs::restart_targets`]: an env in flight into the slot
    /// its command named, as a whole-batch call's envs are).
    pub(super) fn send_restart(&mut self, k: usize) -> Result<(), PoolError> {
        self.workers[k].restarted = true;
        let envs = self.blocks[k].clone();
        let uniform = self.async_api.whole_blocks;
        let targets = self.async_api.envs.restart_targets(envs, uniform);
        self.send_reset(k, Target::Each(&targets), None)
    }

    /// Step command to worker `k`: each env of its block (`actions`) into the slot `target`
    /// names for it (a whole-batch call: every env into one slot; the async API: each env into
    /// its own, 0 leaving it alone, a [`Command::subset`] step of the others); `partial`:
    /// answered env by env ([`Command::partial`]). The one step sender of both APIs. A replaced
    /// worker ([`WorkerLink::cut`]) resets all its envs instead, which report `restarted`:
    /// whether it stepped.
    pub(super) fn send_step(
        &mut self,
        k: usize,
        actions: StepActions<'_>,
        target: Target<'_>,
        partial: bool,
    ) -> Result<bool, PoolError> {
        if self.workers[k].cut {
            self.send_restart(k)?;
            return Ok(false);
        }
        let served = match target {
            Target::Slot(_) => self.blocks[k].len(),
            Target::Each(t) => t.iter().filter(|&&w| w != 0).count(),
        };
        let (slot, each) = target.words();
        let each = each.unwrap_or(&[]);
        let cmd = Command {
            action_extras: self.write_action_extras(k)?,
            subset: !each.is_empty(),
            partial,
            ..self.command(Op::Step, slot)
        };
        let (aw, ab) = (self.spec.action_words(), self.spec.action_bytes);
        let words = self.blocks[k].len() * aw;
        let s = &mut self.workers[k];
        s.seq = next_seq(s.seq, s.delivered);
        s.served += served as u64;
        s.ports
            .send_cmd(s.seq, cmd.encode(), words + each.len(), |p| {
                let (a, o) = p.split_at_mut(words);
                actions.write(a, aw, ab);
                o.copy_from_slice(each);
            })?;
        if !(partial && s.partial) {
            // A worker already answering partial commands stays pending since its oldest.
            s.pending_now();
        }
        s.partial |= partial;
        Ok(true)
    }
}
