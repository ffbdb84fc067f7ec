//! The async API's ready set, and the rule of fair service.
//!
//! Each env sent takes the next ticket of one counter (the envs of one `send` in the order
//! given). The envs whose results are ready are kept by ticket, so `recv` hands over the env
//! sent first, whatever its worker and whenever its answer arrived: a worker that runs late
//! (a busy machine) loses no turns, its envs once answered going before envs sent after
//! them. And where the env sent first is not ready yet but only a little late (within the
//! usual answer time and as much again, at most [`PATIENCE`] more: [`ReadySet::patience`]),
//! `recv` waits that long for it rather than hand over envs sent after it, so that a worker
//! that wakes a little later than its mates (on a core shared with the caller) is not passed
//! over again and again; an env much later than usual (a slow reset) is not waited for.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// The most a `recv` waits past the usual answer time for the env sent first
/// ([`ReadySet::patience`]): about what a wake-up across cores costs on a busy VM, twice.
pub(super) const PATIENCE: Duration = Duration::from_micros(200);

/// The envs sent and not yet handed over, by ticket: those whose result is ready, and those
/// still on their way.
pub(super) struct ReadySet {
    /// The ready envs by ticket: the first is the one sent first.
    ready: BTreeMap<u64, usize>,
    /// The envs sent and not ready yet, by ticket.
    pending: BTreeMap<u64, usize>,
    /// Each env's ticket (from its last send) and when it was sent; the next ticket.
    ticket: Vec<u64>,
    sent_at: Vec<Instant>,
    next_ticket: u64,
    /// The usual time from a send to its answer (a moving average), ns; 0 before the first.
    usual_ns: u64,
}

impl ReadySet {
    /// The set of a pool of `num_envs` envs, empty.
    pub(super) fn new(num_envs: usize) -> Self {
        ReadySet {
            ready: BTreeMap::new(),
            pending: BTreeMap::new(),
            ticket: vec![0; num_envs],
            sent_at: vec![Instant::now(); num_envs],
            next_ticket: 0,
            usual_ns: 0,
        }
    }

    /// Forget every env (a reset starts them all afresh).
    pub(super) fn clear(&mut self) {
        self.ready.clear();
        self.pending.clear();
    }

    /// Env `e` was sent just now: it takes the next ticket.
    pub(super) fn sent(&mut self, e: usize) {
        self.ticket[e] = self.next_ticket;
        self.next_ticket += 1;
        self.sent_at[e] = Instant::now();
        self.pending.insert(self.ticket[e], e);
    }

    /// Env `e`'s result is ready: in the set at its ticket; its time from send to answer feeds
    /// the usual one.
    pub(super) fn ready(&mut self, e: usize) {
        self.ready.insert(self.ticket[e], e);
        if self.pending.remove(&self.ticket[e]).is_some() {
            let took = self.sent_at[e]
                .elapsed()
                .as_nanos()
                .min(u128::from(u32::MAX)) as u64;
            // A rare long one (a slow reset) moves the usual by a few times it at most.
            self.usual_ns = match self.usual_ns {
                0 => took,
                u => (u * 7 + took.min(4 * u)) / 8,
            };
        }
    }

    /// Env `e` will not answer (it failed): no longer on its way.
    pub(super) fn dropped(&mut self, e: usize) {
        self.pending.remove(&self.ticket[e]);
    }

    /// Envs whose result is ready.
    pub(super) fn len(&self) -> usize {
        self.ready.len()
    }

    /// The ready env sent first, if any.
    pub(super) fn first(&self) -> Option<usize> {
        self.ready.first_key_value().map(|(_, &e)| e)
    }

    /// The first `n` ready envs, in the order they will be handed over.
    pub(super) fn peek(&self, n: usize) -> impl Iterator<Item = usize> + '_ {
        self.ready.values().take(n).copied()
    }

    /// Take the ready env sent first.
    pub(super) fn pop(&mut self) -> Option<usize> {
        self.ready.pop_first().map(|(_, e)| e)
    }

    /// Until when a `recv` that has enough envs ready waits for the env sent first, when that
    /// one is not ready yet but only a little late: sent before every ready env, within the
    /// usual answer time and as much again, at most [`PATIENCE`] more (`None`: hand over what
    /// is ready now).
    pub(super) fn patience(&self, now: Instant) -> Option<Instant> {
        let (&t, &e) = self.pending.first_key_value()?;
        if self.ready.first_key_value().is_some_and(|(&r, _)| r < t) || self.usual_ns == 0 {
            return None;
        }
        let usual = Duration::from_nanos(self.usual_ns);
        let until = self.sent_at[e] + usual + usual.min(PATIENCE);
        (now < until).then_some(until)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_env_sent_first_is_handed_over_first_whenever_it_became_ready() {
        let mut s = ReadySet::new(4);
        for e in [2, 0, 3, 1] {
            s.sent(e);
        }
        // Answers arrive in another order than the sends.
        for e in [1, 3, 0] {
            s.ready(e);
        }
        assert_eq!(s.peek(3).collect::<Vec<_>>(), vec![0, 3, 1]);
        assert_eq!((s.pop(), s.len()), (Some(0), 2));
        s.ready(2);
        assert_eq!(
            s.first(),
            Some(2),
            "sent first, answered last, served first"
        );
    }

    #[test]
    fn a_little_late_first_env_is_waited_for_a_much_later_one_is_not() {
        let mut s = ReadySet::new(3);
        let t0 = Instant::now();
        s.sent(0);
        s.sent(1);
        assert_eq!(
            s.patience(t0),
            None,
            "no usual answer time yet: nothing to wait by"
        );
        s.ready(1);
        // Env 0 was sent before the ready env 1: worth a wait, but only a short one.
        // Asked at the moment env 1 was sent (a loaded machine may run this test long after).
        let until = s
            .patience(s.sent_at[1])
            .expect("env 0 is only a little late");
        assert!(until <= s.sent_at[0] + 2 * Duration::from_nanos(s.usual_ns) + PATIENCE);
        assert_eq!(
            s.patience(until),
            None,
            "past its patience: hand over what is ready"
        );
        s.ready(0);
        assert_eq!(
            s.patience(Instant::now()),
            None,
            "the env sent first is ready"
        );
        s.sent(2);
        s.dropped(2);
        assert_eq!(
            s.patience(Instant::now()),
            None,
            "a failed env is not waited for"
        );
    }
}
