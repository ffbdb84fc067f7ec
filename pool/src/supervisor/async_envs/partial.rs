//! Envs in flight under partial commands: a worker whose envs run on threads answers each env
//! as it finishes ([`crate::wire::Command::partial`]), so each is followed on its own: the
//! command it went with and when, until its rows arrive or it fails.

use std::time::Instant;

use super::{AsyncEnvs, Turn};
use crate::supervisor::intake::Apart;
use crate::wire::answer::Answer;

impl AsyncEnvs {
    /// The last `count` envs dispatched to worker `k` went with partial command `seq`.
    pub(in crate::supervisor) fn sent_partial(&mut self, k: usize, count: usize, seq: u64) {
        let now = Instant::now();
        let sent = &self.sent[k];
        for r in &sent[sent.len().saturating_sub(count)..] {
            self.partial[r.clone()].fill(Some((seq, now)));
        }
    }

    /// When the oldest env in flight with worker `k` under a partial command was sent.
    pub(in crate::supervisor) fn oldest_partial(&self, k: usize) -> Option<Instant> {
        (self.sent[k].iter().flat_map(|r| r.clone()))
            .filter_map(|e| self.partial[e].map(|(_, t)| t))
            .min()
    }

    /// Envs `envs` of worker `k`, in flight under partial commands, are done (`answer`: what
    /// the worker said of them): their rows are in their slots, and `apart` has the extra
    /// info that did not fit their rooms. An env not in flight so is the worker's error (the
    /// string says which), and nothing is taken.
    pub(in crate::supervisor) fn arrive_rows(
        &mut self,
        k: usize,
        envs: &[usize],
        answer: &Answer,
        mut apart: Apart,
    ) -> Result<(), String> {
        if let Some(&e) = envs
            .iter()
            .find(|&&e| self.partial[e].is_none() || !self.sent[k].contains(&(e..e + 1)))
        {
            return Err(format!(
                "an answer for env {e}, which is not in flight with it"
            ));
        }
        for &e in envs {
            if self.partial[e].take().is_none() {
                continue;
            }
            self.sent[k].retain(|r| *r != (e..e + 1));
            let run = self.answered(e..e + 1, answer, &mut apart);
            self.push_ready(run);
        }
        Ok(())
    }

    /// Env `e` of worker `k` failed under a partial command: it is no longer in flight (the
    /// failure is raised, and a reset starts it afresh).
    pub(in crate::supervisor) fn fail_row(&mut self, k: usize, e: usize) {
        if self.partial[e].take().is_some() {
            self.sent[k].retain(|r| *r != (e..e + 1));
            self.set_turn(e, Turn::Caller);
            self.ready.dropped(e);
        }
    }
}
