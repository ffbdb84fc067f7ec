//! A reset or step command as the worker checks it, once, whichever executor serves it: its
//! words per env and the batch slot each env of the block writes in ([`Named`]).

use super::{Worker, WorkerError};
use crate::wire::{Command, Op};

/// The slot (`s + 1`) each env of the block writes in under a reset or step.
#[derive(Clone, Copy)]
pub(super) enum Slots<'p> {
    /// Every env into this one.
    All(u64),
    /// Each env into its own (a [`Command::subset`] command; 0: left alone).
    Each(&'p [u64]),
}

impl Slots<'_> {
    /// The slot (`s + 1`) of the block's env `j`; 0: not one of the command's.
    pub(super) fn of(self, j: usize) -> u64 {
        match self {
            Slots::All(t) => t,
            Slots::Each(t) => t[j],
        }
    }

    /// The slots written, each once, in order (`1..=slots`).
    pub(super) fn written(self, slots: u64) -> impl Iterator<Item = u64> {
        (1..=slots).filter(move |s| match self {
            Slots::All(t) => t == *s,
            Slots::Each(t) => t.contains(s),
        })
    }
}

/// A reset or step's payload, checked: its words per env (an episode index for a reset, the
/// action words for a step), those words, and each env's slot.
pub(super) struct Named<'p> {
    pub(super) per_env: usize,
    pub(super) words: &'p [u64],
    pub(super) slots: Slots<'p>,
}

impl Worker<'_> {
    /// Check command `seq`'s `payload` (a reset or step): as many words as the block's envs
    /// take, and every slot in the pool. The one check of both executors: an error ends the
    /// worker (the supervisor sent what no supervisor sends).
    pub(super) fn check_command<'p>(
        &self,
        seq: u64,
        command: &Command,
        payload: &'p [u64],
    ) -> Result<Named<'p>, WorkerError> {
        let epw = self.block_envs;
        let per_env = if command.op == Op::Step {
            self.action_words
        } else {
            1
        };
        let subset = command.subset;
        let n = payload.len();
        if n != epw * per_env + if subset { epw } else { 0 } {
            return Err(WorkerError::Msg(format!(
                "command {seq} carries {n} words for {epw} envs of {per_env} words (subset: \
                 {subset})"
            )));
        }
        let slots = self.cfg.batch_slots as u64;
        let (words, each) = payload.split_at(epw * per_env);
        let (named, bad) = if subset {
            (Slots::Each(each), each.iter().copied().find(|&w| w > slots))
        } else {
            let t = u64::from(command.target);
            (Slots::All(t), (!(1..=slots).contains(&t)).then_some(t))
        };
        if let Some(t) = bad {
            return Err(WorkerError::Msg(format!(
                "command {seq}: observation target {t}, but the pool has {slots} slots"
            )));
        }
        Ok(Named {
            per_env,
            words,
            slots: named,
        })
    }
}
