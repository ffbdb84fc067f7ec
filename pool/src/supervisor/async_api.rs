//! EnvPool-style async stepping, env by env: `async_reset`, `send` to any envs, and `recv` of
//! the first envs ready, with a deadline if asked ([`RecvWant`]). The per-env bookkeeping is
//! [`super::async_envs`].

use std::time::{Duration, Instant};

use super::actions::Actions;
use super::async_envs::Turn;
use super::commands::StepActions;
use super::intake::runs_into;
use super::link::Target;
use super::{Pool, Supervisor};
use crate::batch::Received;
use crate::error::PoolError;

/// Commands a worker whose envs run on threads may have unread (its command port holds 8:
/// room is left).
const UNREAD: u64 = 6;

/// How many envs an async [`Pool::recv_want`] hands over, and how long it may wait for them:
/// it returns as soon as `max_batch` envs are ready, or at the deadline with every ready env
/// (up to `max_batch`) if at least `min_batch` are; with fewer it fails with
/// [`PoolError::RecvTimeout`] and nothing is lost. With no timeout it waits for `min_batch`
/// and hands over every env ready then (up to `max_batch`). TorchRL's `AsyncEnvPool` names
/// these `min_get`, `max_get` and `timeout`, with the same meaning.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RecvWant {
    /// Envs to return at least (1 or more).
    pub min_batch: usize,
    /// Envs to return at most (`min_batch` or more).
    pub max_batch: usize,
    /// The deadline, from the call's start.
    pub timeout: Option<Duration>,
}

impl RecvWant {
    /// Exactly `n` envs, however long they take (EnvPool's `recv` with `batch_size = n`).
    pub fn exactly(n: usize) -> Self {
        RecvWant {
            min_batch: n,
            max_batch: n,
            timeout: None,
        }
    }

    /// A `recv` of a pool of batch size `batch_size`, as a caller states it, with the
    /// defaults filled in: `max_batch` defaults to `batch_size` (or `min_batch` where that asks
    /// for more), `min_batch` to `max_batch` (at most `batch_size`). [`Pool::recv_want`]
    /// checks the result (its one check, which names the argument that is wrong).
    pub fn resolve(
        min_batch: Option<usize>,
        max_batch: Option<usize>,
        timeout: Option<Duration>,
        batch_size: usize,
    ) -> RecvWant {
        let max = max_batch.unwrap_or_else(|| batch_size.max(min_batch.unwrap_or(1)));
        RecvWant {
            min_batch: min_batch.unwrap_or(max.min(batch_size)),
            max_batch: max,
            timeout,
        }
    }

    /// The check of a `recv` of a pool of `num_envs` envs: each bound 1 to `num_envs`,
    /// `min_batch` at most `max_batch`; the error names the argument.
    fn check(&self, num_envs: usize) -> Result<(), PoolError> {
        for (name, v) in [("min_batch", self.min_batch), ("max_batch", self.max_batch)] {
            if !(1..=num_envs).contains(&v) {
                return Err(PoolError::Config(format!(
                    "recv(): {name} must be between 1 and num_envs ({num_envs}), got {v}"
                )));
            }
        }
        if self.min_batch > self.max_batch {
            return Err(PoolError::Config(format!(
                "recv(): min_batch ({}) must not exceed max_batch ({})",
                self.min_batch, self.max_batch
            )));
        }
        Ok(())
    }
}

impl Pool {
    /// Async: reset every env (as [`Pool::reset`]; outstanding results are discarded); collect
    /// the results with [`Pool::recv`]. It is [`Pool::send_reset`] into a slot the caller has
    /// not lent out, its receive left to `recv`.
    pub fn async_reset(&mut self) -> Result<(), PoolError> {
        let slots = self.sup.cfg.batch_slots;
        let (next, lent) = (self.sup.next_slot, self.sup.async_api.envs.lent);
        self.sup.next_slot = (0..slots)
            .map(|i| (next + i) % slots)
            .find(|s| lent & (1 << s) == 0)
            .unwrap_or(next);
        let slot = self.send_reset(None)?;
        self.sup.call.sent = None;
        self.sup.next_slot = (slot + 1) % slots;
        self.sup.async_api.on = true;
        Ok(())
    }

    /// Async: send actions to envs, any of them, each at most once until it is received;
    /// `actions[r]` is for `env_ids[r]`. An env whose worker is busy with others of its envs
    /// waits for it (it goes with the worker's next command). Envs of a vector env per worker
    /// ([`crate::EnvRegistry::builds_blocks`]) go by whole worker blocks.
    pub fn send<'a>(
        &mut self,
        actions: impl Into<Actions<'a>>,
        env_ids: &[usize],
    ) -> Result<(), PoolError> {
        let actions = actions.into();
        self.begin_call()?;
        self.sup.check_started("send")?;
        actions.check(&self.sup.spec, env_ids.len(), |r| env_ids[r])?;
        self.sup.check_sendable(env_ids)?;
        // A sync reset may start the async API too (as TorchRL's loop does).
        self.sup.async_api.on = true;
        let (ab, aw) = (self.sup.spec.action_bytes, self.sup.spec.action_words());
        let mut words = vec![0u64; aw];
        let (envs, mut r) = (&mut self.sup.async_api.envs, 0);
        while r < env_ids.len() {
            // Consecutive envs of one worker that answers whole commands go as one run.
            let mut end = r + 1;
            while end < env_ids.len()
                && envs.joins(env_ids[end - 1], env_ids[end], self.sup.concurrent)
            {
                end += 1;
            }
            envs.sent_run(env_ids[r]..env_ids[end - 1] + 1);
            for (i, &e) in env_ids.iter().enumerate().take(end).skip(r) {
                StepActions::Rows(actions.rows(i..i + 1, ab)).write(&mut words, aw, ab);
                envs.stage(e, &words);
            }
            r = end;
        }
        // Answers that came meanwhile free their workers for what was just staged.
        self.sup.poll_all()?;
        self.sup.absorb()?;
        self.sup.dispatch_staged()
    }

    /// Async: have [`Pool::recv`] hand rows that are one run of envs in one slot over as a
    /// view ([`Received::view`]) rather than copied (`true`). A view's rows stay put until
    /// those envs' next answer but one (each env's answers take turns over the slots). Off by
    /// default.
    pub fn set_async_views(&mut self, on: bool) {
        self.sup.async_api.envs.views = on;
    }

    /// The batch slots the caller has lent out (bit `s` for slot `s`: it keeps views of them,
    /// as a binding that hands out a whole-batch call's rows without a copy does): until the
    /// next call of this, no async answer is written there. At least one slot must stay free.
    pub fn lend_slots(&mut self, mask: u64) -> Result<(), PoolError> {
        let slots = self.sup.cfg.batch_slots;
        let all = (1u64 << slots) - 1;
        if mask & all == all || mask & !all != 0 {
            return Err(PoolError::Config(format!(
                "lend_slots({mask:#b}): the pool has {slots} slots, of which at least one must stay free"
            )));
        }
        self.sup.async_api.envs.lent = mask;
        Ok(())
    }

    /// Async: wait for the next `batch_size` envs and hand them over, first ready first.
    pub fn recv(&mut self) -> Result<Received, PoolError> {
        self.recv_want(RecvWant::exactly(self.batch_size()))
    }

    /// Async: hand over the first envs ready, as many and within the time `want` says.
    pub fn recv_want(&mut self, want: RecvWant) -> Result<Received, PoolError> {
        self.begin_call()?;
        want.check(self.sup.cfg.num_envs)?;
        self.sup.check_started("recv")?;
        let outstanding = self.sup.async_api.envs.outstanding();
        if outstanding < want.min_batch {
            return Err(PoolError::State(format!(
                "recv() needs {} envs sent and not yet received but only {outstanding} are: send() actions (or async_reset()) first",
                want.min_batch
            )));
        }
        let until = want.timeout.map(|t| Instant::now() + t);
        let Some(got) = self.receive(want, until, false)? else {
            return Err(PoolError::RecvTimeout {
                ready: self.sup.async_api.envs.num_ready(),
                min_batch: want.min_batch,
                timeout: want.timeout.unwrap_or_default(),
            });
        };
        // The rows' own replacements by plan, whenever their worker was replaced.
        self.sup.recycling.replaced_envs.clone_from(&got.recycled);
        Ok(got)
    }

    /// The one wait of the lane, for a `recv` and a whole-batch call (`whole`: every env, in
    /// env order, as a view of its slot): hand over the first envs ready, as many as `want`
    /// says, once enough are (`until`: give up then with `None`, nothing lost).
    pub(super) fn receive(
        &mut self,
        want: RecvWant,
        until: Option<Instant>,
        whole: bool,
    ) -> Result<Option<Received>, PoolError> {
        let max = want.max_batch.min(self.sup.async_api.envs.outstanding());
        let enough = if until.is_some() { max } else { want.min_batch };
        let mut done;
        loop {
            // Enough ready, and the env sent first ready too, unless it is late beyond the
            // usual (fair service: `ready_set.rs`); a wait for it ends at its patience. (A
            // whole-batch call waits for every env anyway.)
            let patience = match whole {
                true => None,
                false => self.sup.async_api.envs.patience(Instant::now()),
            };
            let stop = match (until, patience) {
                (Some(u), Some(p)) => Some(u.min(p)),
                (u, p) => u.or(p),
            };
            done = self.wait_for(
                |c| {
                    c.absorb()?;
                    let envs = &c.async_api.envs;
                    let first_in = || whole || envs.patience(Instant::now()).is_none();
                    Ok(envs.num_ready() >= enough && first_in())
                },
                stop,
            )?;
            let past = until.is_some_and(|u| Instant::now() >= u);
            if done || past || self.sup.async_api.envs.num_ready() >= enough {
                done |= self.sup.async_api.envs.num_ready() >= enough;
                break;
            }
        }
        if !done && self.sup.async_api.envs.num_ready() < want.min_batch {
            return Ok(None);
        }
        let c = &mut self.sup;
        if c.slots.is_empty() {
            return Err(PoolError::Closed);
        }
        let ob = c.spec.obs_bytes();
        Ok(Some(c.async_api.envs.take(max, whole, ob, &c.slots)))
    }
}

impl Supervisor {
    /// Fail a `send` or `recv` that needs an `async_reset` first: with the failures that made
    /// it so, if they were seen outside a wait (by a `send`) and not raised yet; or that comes
    /// between the halves of a whole-batch call.
    fn check_started(&mut self, call: &str) -> Result<(), PoolError> {
        if self.call.sent.is_some() {
            return Err(PoolError::State(format!(
                "a step or reset is pending: wait() for it before {call}()"
            )));
        }
        if !self.failures.must_reset {
            return Ok(());
        }
        if !self.call.faults.is_empty() {
            let all = std::mem::take(&mut self.call.faults);
            return Err(PoolError::collected(all).unwrap_or(PoolError::Interrupted));
        }
        Err(PoolError::State(format!(
            "call async_reset() before {call}() (after creation or after a failure)"
        )))
    }

    /// Refuse to send to an env twice before it is received, to an env out of range, or (a
    /// vector env per worker) to part of a worker block.
    fn check_sendable(&self, env_ids: &[usize]) -> Result<(), PoolError> {
        let n = self.cfg.num_envs;
        let mut seen = vec![false; n];
        for &e in env_ids {
            if e >= n {
                return Err(PoolError::State(format!(
                    "send() to env {e}, but the pool has envs 0 to {}",
                    n - 1
                )));
            }
            let why = match self.async_api.envs.turn(e) {
                _ if seen[e] => "appears twice in env_ids",
                Turn::Caller => "",
                Turn::Staged | Turn::InFlight => {
                    "is in flight (sent and not yet received): recv() it before sending to it again"
                }
                Turn::Ready => "has a result waiting: recv() it before sending to it again",
            };
            if !why.is_empty() {
                return Err(PoolError::State(format!("send(): env {e} {why}")));
            }
            seen[e] = true;
        }
        if self.async_api.whole_blocks
            && let Some(b) = self.blocks.iter().find(|b| {
                let mut r = (*b).clone();
                let some = r.clone().any(|e| seen[e]);
                some && !r.all(|e| seen[e])
            })
        {
            return Err(PoolError::State(format!(
                "send(): each worker steps its vector env as a whole, so send to all envs of a worker block at once ({b:?}), or to none"
            )));
        }
        Ok(())
    }

    /// Turn the workers' answers into ready envs (the ready set orders them by when they were
    /// sent: `async_envs/`), and send what is staged to the workers that are free.
    pub(super) fn absorb(&mut self) -> Result<(), PoolError> {
        while let Some(k) = self.arrived.pop_front() {
            self.take_async_answer(k)?;
        }
        self.dispatch_staged()
    }

    /// Take worker `k`'s answer to its outstanding command, checked as a whole-batch call's
    /// is (its words, the flag bytes of the rows it wrote, its side file): its envs are
    /// ready. A bad answer is the worker's failure.
    fn take_async_answer(&mut self, k: usize) -> Result<(), PoolError> {
        let block = self.blocks[k].clone();
        let served = |c: &Self, restart: bool, out: &mut _| {
            let envs = &c.async_api.envs;
            let slot_of = |e| envs.last_slot(e);
            match restart {
                true => runs_into(block.clone().map(|e| e..e + 1), slot_of, out),
                false => runs_into(envs.sent_to(k).iter().cloned(), slot_of, out),
            }
        };
        let Some(t) = self.take_checked(k, served)? else {
            return Ok(());
        };
        self.call.ready_ns = self.call.ready_ns.max(t.ready_ns);
        let restart = t.restart.then_some(t.recycled);
        self.async_api
            .envs
            .arrive(k, block, &t.answer, t.apart, restart);
        Ok(())
    }

    /// Send each free worker the envs staged for it.
    pub(super) fn dispatch_staged(&mut self) -> Result<(), PoolError> {
        if self.async_api.envs.num_staged == 0 {
            return Ok(());
        }
        for k in 0..self.workers.len() {
            if !self.async_api.envs.has_staged(k) {
                continue;
            }
            // Planned replacements happen here, between two commands (see `recycling`); a
            // worker replaced now takes its staged envs once it is back.
            if self.recycle_if_due(k)? {
                continue;
            }
            // A worker whose envs run on threads takes more partial commands while some of
            // its envs are in flight, as long as its command port has room (it holds 8: at
            // most `UNREAD` commands unread); any other, one command at a time.
            let busy_partial = self.workers[k].partial && self.workers[k].state.is_pending();
            let idle = self.workers[k].state.is_idle();
            let w = &self.workers[k];
            let read = self.stats.as_ref().map_or(0, |s| s.read(k));
            let unread = (w.ports.sent() - w.sent_before).saturating_sub(read);
            let room = busy_partial && unread < UNREAD;
            if !(idle || room) {
                continue;
            }
            let envs = self.blocks[k].clone();
            let Some((words, targets)) = self.async_api.envs.dispatch(k, envs) else {
                continue;
            };
            let partial = self.concurrent;
            let count = targets.iter().filter(|&&t| t != 0).count();
            let (actions, target) = (StepActions::Words(&words), Target::Each(&targets));
            if self.send_step(k, actions, target, partial)? && partial {
                let seq = self.workers[k].seq;
                self.async_api.envs.sent_partial(k, count, seq);
            }
        }
        Ok(())
    }
}
