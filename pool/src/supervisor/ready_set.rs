//! The ready set of the pool's one lane, the rule of fair service, and how ready runs are
//! handed over (a view's extra info, gathered rows).
//!
//! Every send is of runs of envs: an async `send` sends each env as a run of its own (in the
//! order given), a whole-batch call each worker block as one run (in block order, so its
//! envs come back in env order: `order = i`). Each run takes the next ticket of one counter.
//! The runs whose answers are in are kept by ticket, so a receive hands over the env sent
//! first, whatever its worker and whenever its answer arrived: a worker that runs late (a
//! busy machine) loses no turns, its envs once answered going before envs sent after them.
//! And where the run sent first is not ready yet but only a little late (within the usual
//! answer time and as much again, at most [`PATIENCE`] more: [`ReadySet::patience`]), a
//! `recv` waits that long for it rather than hand over envs sent after it, so that a worker
//! that wakes a little later than its mates (on a core shared with the caller) is not passed
//! over again and again; an env much later than usual (a slow reset) is not waited for.

use std::collections::BTreeMap;
use std::ops::Range;
use std::time::{Duration, Instant};

use super::intake::{Apart, slot_extra};
use crate::batch::{Received, SlotExtras};
use crate::wire::answer::AnswerExtras;
use crate::wire::slot_layout::SlotRows;

/// The most a `recv` waits past the usual answer time for the env sent first
/// ([`ReadySet::patience`]): about what a wake-up across cores costs on a busy VM, twice.
pub(super) const PATIENCE: Duration = Duration::from_micros(200);

/// A run of envs sent together whose answer is in: their rows in batch slot `slot`.
#[derive(Debug)]
pub(super) struct Run {
    /// The envs, consecutive and of one worker.
    pub(super) envs: Range<usize>,
    pub(super) slot: usize,
    /// It answers a restart of its worker (its rows say so, and carry no extra info), by plan
    /// (`recycled`) or after a failure.
    pub(super) restart: bool,
    pub(super) recycled: bool,
    /// What the worker's answer said of its envs' extra info and final observations.
    pub(super) extras: AnswerExtras,
    pub(super) final_obs: bool,
    /// The extra info of its envs that travelled beside the answer.
    pub(super) apart: Apart,
}

impl Run {
    /// The run of `envs` in `slot` answering a restart of their worker.
    pub(super) fn restart(envs: Range<usize>, slot: usize, recycled: bool) -> Self {
        Run {
            envs,
            slot,
            restart: true,
            recycled,
            extras: AnswerExtras::None,
            final_obs: false,
            apart: Vec::new(),
        }
    }
}

/// The first rows of the envs the caller held when their worker was restarted, each kept for
/// the env's next send or whole-batch call, which hands them over.
pub(super) struct HeldRestarts {
    runs: Vec<Option<Run>>,
    held: usize,
}

impl HeldRestarts {
    /// None kept, for `num_envs` envs.
    pub(super) fn new(num_envs: usize) -> Self {
        HeldRestarts {
            runs: (0..num_envs).map(|_| None).collect(),
            held: 0,
        }
    }

    /// Keep `run`, env `e`'s restart (in place of one kept before).
    pub(super) fn keep(&mut self, e: usize, run: Run) {
        self.held += usize::from(self.runs[e].replace(run).is_none());
    }

    /// Env `e`'s restart, no longer kept.
    pub(super) fn take(&mut self, e: usize) -> Option<Run> {
        let run = self.runs[e].take();
        self.held -= usize::from(run.is_some());
        run
    }

    /// Whether env `e`'s restart is kept.
    pub(super) fn holds(&self, e: usize) -> bool {
        self.runs[e].is_some()
    }

    /// Whether any is kept.
    pub(super) fn any(&self) -> bool {
        self.held > 0
    }

    /// Keep none.
    pub(super) fn clear(&mut self) {
        self.runs.iter_mut().for_each(|r| *r = None);
        self.held = 0;
    }
}

/// The runs sent and not yet handed over, by ticket: those whose answer is in, and those still
/// on their way.
pub(super) struct ReadySet {
    /// The ready runs by ticket (the first is the one sent first), and their envs.
    ready: BTreeMap<u64, Run>,
    ready_envs: usize,
    /// The runs sent and not ready yet: when each was sent, by ticket.
    pending: BTreeMap<u64, Instant>,
    /// Each env's ticket (of its run's last send); the next ticket.
    ticket: Vec<u64>,
    next_ticket: u64,
    /// The usual time from a send to its answer (a moving average), ns; 0 before the first.
    usual_ns: u64,
}

impl ReadySet {
    /// The set of a pool of `num_envs` envs, empty.
    pub(super) fn new(num_envs: usize) -> Self {
        ReadySet {
            ready: BTreeMap::new(),
            ready_envs: 0,
            pending: BTreeMap::new(),
            ticket: vec![0; num_envs],
            next_ticket: 0,
            usual_ns: 0,
        }
    }

    /// Forget every run (a reset starts every env afresh).
    pub(super) fn clear(&mut self) {
        self.ready.clear();
        self.ready_envs = 0;
        self.pending.clear();
    }

    /// The run `envs` was sent just now: it takes the next ticket.
    pub(super) fn sent(&mut self, envs: Range<usize>) {
        let t = self.next_ticket;
        self.next_ticket += 1;
        self.ticket[envs].fill(t);
        self.pending.insert(t, Instant::now());
    }

    /// Whether envs `a` and `b` went in one run (the same send).
    pub(super) fn same_run(&self, a: usize, b: usize) -> bool {
        self.ticket[a] == self.ticket[b]
    }

    /// The answer of a run is in (`run.envs`: all of its envs, or the rest of them when some
    /// failed): in the set at its ticket; its time from send to answer feeds the usual one.
    pub(super) fn ready(&mut self, run: Run) {
        let t = self.ticket[run.envs.start];
        if let Some(sent_at) = self.pending.remove(&t) {
            let took = sent_at.elapsed().as_nanos().min(u128::from(u32::MAX)) as u64;
            // A rare long one (a slow reset) moves the usual by a few times it at most.
            self.usual_ns = match self.usual_ns {
                0 => took,
                u => (u * 7 + took.min(4 * u)) / 8,
            };
        }
        self.ready_envs += run.envs.len();
        self.ready.insert(t, run);
    }

    /// The ready run env `e` is in.
    pub(super) fn ready_run(&mut self, e: usize) -> Option<&mut Run> {
        self.ready.get_mut(&self.ticket[e])
    }

    /// Env `e`'s run will not answer (it failed): no longer on its way.
    pub(super) fn dropped(&mut self, e: usize) {
        self.pending.remove(&self.ticket[e]);
    }

    /// Envs whose answer is in.
    pub(super) fn len(&self) -> usize {
        self.ready_envs
    }

    /// Take the ready run sent first, at most `max` envs of it (the rest stays, first in
    /// turn).
    pub(super) fn pop(&mut self, max: usize) -> Option<Run> {
        let (t, mut run) = self.ready.pop_first()?;
        if run.envs.len() > max {
            let rest = run.envs.start + max..run.envs.end;
            let apart = run
                .apart
                .extract_if(.., |(e, _)| rest.contains(e))
                .collect();
            self.ready.insert(
                t,
                Run {
                    envs: rest,
                    apart,
                    ..run
                },
            );
            run.envs.end = run.envs.start + max;
        }
        self.ready_envs -= run.envs.len();
        Some(run)
    }

    /// Until when a `recv` that has enough envs ready waits for the run sent first, when that
    /// one is not ready yet but only a little late: sent before every ready run, within the
    /// usual answer time and as much again, at most [`PATIENCE`] more (`None`: hand over what
    /// is ready now).
    pub(super) fn patience(&self, now: Instant) -> Option<Instant> {
        let (&t, &sent_at) = self.pending.first_key_value()?;
        if self.ready.first_key_value().is_some_and(|(&r, _)| r < t) || self.usual_ns == 0 {
            return None;
        }
        let usual = Duration::from_nanos(self.usual_ns);
        let until = sent_at + usual + usual.min(PATIENCE);
        (now < until).then_some(until)
    }
}

/// The extra info of a view's runs (its first env `first`): read in place when every run's
/// envs wrote one layout, else joined row by row.
pub(super) fn view_extras(runs: &[Run], slots: &[SlotRows], first: usize) -> SlotExtras {
    let mut uniform = None;
    let (mut any, mut not_uniform) = (false, false);
    for r in runs {
        any |= !r.apart.is_empty();
        not_uniform |= r.restart || !r.apart.is_empty();
        match r.extras {
            _ if r.restart => {}
            AnswerExtras::None => not_uniform = true,
            AnswerExtras::Mixed => (any, not_uniform) = (true, true),
            AnswerExtras::Uniform { size, head } => {
                any = true;
                not_uniform |= uniform.is_some_and(|u| u != (size, head));
                uniform = Some((size, head));
            }
        }
    }
    match (any, not_uniform, uniform) {
        (false, _, _) => SlotExtras::None,
        (true, false, Some((size, _))) => SlotExtras::Uniform(size),
        _ => {
            let mut out = Vec::new();
            for r in runs {
                let w = &slots[r.slot];
                for e in r.envs.clone() {
                    out.extend(run_extra(r, w, e, &w.read(e)).map(|x| (e - first, x)));
                }
            }
            SlotExtras::Rows(out)
        }
    }
}

/// Env `e`'s extra info in run `r` (`rec`: its record in the run's slot `w`).
fn run_extra(
    r: &Run,
    w: &SlotRows,
    e: usize,
    rec: &crate::wire::record::EnvRecord,
) -> Option<Vec<u8>> {
    if r.restart {
        return None;
    }
    match r.apart.iter().find(|(a, _)| *a == e) {
        Some((_, b)) => Some(b.clone()),
        None if r.extras == AnswerExtras::None => None,
        None => slot_extra(w, e, rec, None),
    }
}

/// Copy the runs' rows out into `out`: records (restart flags applied), observations, extra
/// info by row.
pub(super) fn gather(runs: &[Run], obs_bytes: usize, slots: &[SlotRows], out: &mut Received) {
    let n: usize = runs.iter().map(|r| r.envs.len()).sum();
    out.records.reserve(n);
    out.obs.reserve(n * obs_bytes);
    let mut extras = Vec::new();
    for r in runs {
        let w = &slots[r.slot];
        for e in r.envs.clone() {
            if !r.restart {
                w.clear_restarted(e); // a worker cannot know it: the supervisor's to say
            }
            let rec = w.read(e);
            // SAFETY: env `e`'s rows of the slot: its worker answered, and no command writes
            // them again until the caller sends to `e`.
            out.obs.extend_from_slice(unsafe { w.obs_rows(e..e + 1) });
            extras.extend(run_extra(r, w, e, &rec).map(|x| (out.records.len(), x)));
            out.records.push(rec);
        }
    }
    if !extras.is_empty() {
        out.extras = SlotExtras::Rows(extras);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(envs: Range<usize>) -> Run {
        Run {
            restart: false,
            ..Run::restart(envs, 0, false)
        }
    }

    fn firsts(s: &mut ReadySet, n: usize) -> Vec<Range<usize>> {
        (0..n)
            .filter_map(|_| s.pop(usize::MAX))
            .map(|r| r.envs)
            .collect()
    }

    #[test]
    fn the_run_sent_first_is_handed_over_first_whenever_it_became_ready() {
        let mut s = ReadySet::new(4);
        for e in [2, 0, 3, 1] {
            s.sent(e..e + 1);
        }
        // Answers arrive in another order than the sends.
        for e in [1, 3, 0] {
            s.ready(run(e..e + 1));
        }
        assert_eq!(s.len(), 3);
        assert_eq!(s.pop(1).map(|r| r.envs), Some(0..1));
        s.ready(run(2..3));
        assert_eq!(
            firsts(&mut s, 3),
            vec![2..3, 3..4, 1..2],
            "sent first, served first"
        );
        assert_eq!(s.len(), 0);
    }

    #[test]
    fn a_whole_batch_call_comes_back_in_env_order_and_splits_as_asked() {
        // Two worker blocks sent as runs; the second answers first.
        let mut s = ReadySet::new(6);
        s.sent(0..4);
        s.sent(4..6);
        assert!(s.same_run(0, 3) && !s.same_run(3, 4));
        s.ready(run(4..6));
        let mut first = run(0..4);
        first.apart = vec![(1, vec![1]), (3, vec![3])];
        s.ready(first);
        assert_eq!(s.len(), 6);
        let head = s.pop(3).expect("a run is ready");
        assert_eq!((head.envs, head.apart), (0..3, vec![(1, vec![1])]));
        let rest = s.pop(usize::MAX).expect("the rest stays first in turn");
        assert_eq!((rest.envs, rest.apart), (3..4, vec![(3, vec![3])]));
        assert_eq!(firsts(&mut s, 2), vec![4..6]);
    }

    #[test]
    fn a_little_late_first_run_is_waited_for_a_much_later_one_is_not() {
        let mut s = ReadySet::new(3);
        let t0 = Instant::now();
        s.sent(0..1);
        s.sent(1..2);
        let sent_at = |s: &ReadySet, e: usize| s.pending[&s.ticket[e]];
        let (at0, at1) = (sent_at(&s, 0), sent_at(&s, 1));
        assert_eq!(
            s.patience(t0),
            None,
            "no usual answer time yet: nothing to wait by"
        );
        s.ready(run(1..2));
        // Env 0 was sent before the ready env 1: worth a wait, but only a short one.
        // Asked at the moment env 1 was sent (a loaded machine may run this test long after).
        let until = s.patience(at1).expect("env 0 is only a little late");
        assert!(until <= at0 + 2 * Duration::from_nanos(s.usual_ns) + PATIENCE);
        assert_eq!(
            s.patience(until),
            None,
            "past its patience: hand over what is ready"
        );
        s.ready(run(0..1));
        assert_eq!(
            s.patience(Instant::now()),
            None,
            "the env sent first is ready"
        );
        s.sent(2..3);
        s.dropped(2);
        assert_eq!(
            s.patience(Instant::now()),
            None,
            "a failed env is not waited for"
        );
    }
}
