//! The machine as one pool sees it: its usable cores ([`rogue_gym_ipc::cores`]) and the other
//! live pools of its user ([`rogue_gym_ipc::ledger`]), from which it decides how to wait.
//!
//! The machine's demand, as this pool counts it: its own workers, and for every other live pool
//! its workers and its caller (each other pool is taken to be busy: its caller runs between its
//! calls while this pool's workers step). Alone, the demand is this pool's workers, and the
//! rules are those a pool always had:
//!
//! * its workers block for their next command at once, without polling, when the demand is
//!   more than the cores (in the async API from as many as the cores): a poller takes a core
//!   from a process with work;
//! * its caller polls through a call only when the demand leaves it a core (less than the
//!   cores), and otherwise waits by the pool's own policy (a short yielding poll, then blocks).
//!
//! With other pools on the machine no side polls long: workers poll for the pool's base
//! budget only ([`Pace::Short`]) rather than for the gap their caller usually leaves, and
//! block at once only in the async API past the cores. Blocking at once on every call was
//! measured worse than short yielding polls: a wake-up costs more on this kind of machine than
//! a poll that yields its core (benchmarks/results/many_pools/README.md).
//!
//! The ledger is read again at most once a second (a call checks a clock, no system call), so
//! pools that come and go are seen within a second; this pool's own entry says whether its
//! caller polls, for the others' `stats()` and `doctor`.

use std::time::{Duration, Instant};

use rogue_gym_ipc::ledger::{Entry, Ledger, free_cores};

use crate::config::CpuAffinity;
use crate::error::PoolError;
use crate::wire::Pace;

/// How often the ledger is read again.
const REFRESH: Duration = Duration::from_secs(1);

/// The machine as this pool sees it.
pub(super) struct Machine {
    ledger: Ledger,
    /// This pool's entry.
    me: Entry,
    /// The cores this process may use at once.
    pub(super) cores: usize,
    /// The other live pools at the last reading.
    others: Vec<Entry>,
    read_at: Instant,
}

/// A snapshot of the machine for `stats()`: usable cores, the demand, the other pools.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct MachineView {
    /// The cores this process may use at once.
    pub cores: usize,
    /// The demand this pool counts (see [`crate::supervisor`]'s `machine` module).
    pub demand: usize,
    /// How this pool's workers wait for their next command in sync calls: `"expected"` (poll
    /// for their caller's usual gap), `"short"` (the base poll, other pools share the
    /// machine) or `"block"`.
    pub worker_pace: &'static str,
    /// Whether this pool's caller polls for answers.
    pub caller_polls: bool,
    /// The other live pools of the user: `(name, pid, workers, caller polls, pinned cores)`.
    pub others: Vec<(String, u32, usize, bool, Vec<usize>)>,
}

impl Machine {
    /// Record pool `pool` of `workers` workers in the ledger of `runtime_dir`, its workers
    /// pinned as `affinity` asks: the cores each worker runs on (`None`: the kernel places
    /// them). Disjoint cores are taken under the ledger's lock; too few free ones is an error
    /// that says which pools hold the others.
    pub(super) fn join(
        runtime_dir: &std::path::Path,
        pool: &str,
        workers: usize,
        affinity: Option<CpuAffinity>,
    ) -> Result<(Machine, Option<Vec<usize>>), PoolError> {
        let ledger = Ledger::open(runtime_dir)?;
        let cores = rogue_gym_ipc::usable_cores();
        let allowed = allowed_cores();
        // Under the lock: two pools starting together never take the same cores.
        let lock = ledger.lock()?;
        let pinned: Option<Vec<usize>> = match affinity {
            None => None,
            Some(CpuAffinity::Offset(o)) => Some(
                (0..workers)
                    .map(|k| allowed[(o + k) % allowed.len()])
                    .collect(),
            ),
            Some(CpuAffinity::Disjoint) => {
                let others = ledger.read();
                let Some(free) = free_cores(&allowed, &others, workers) else {
                    let held: Vec<String> = (others.iter())
                        .filter(|e| !e.cores.is_empty())
                        .map(|e| format!("{} (pid {}) cores {:?}", e.pool, e.pid, e.cores))
                        .collect();
                    return Err(PoolError::Config(format!(
                        "cpu_affinity=\"disjoint\": each of the pool's {workers} worker(s) needs \
                         a core of its own, but this process may use {} cores ({allowed:?}) and \
                         other pools hold {}: use fewer workers, close a pool, or pin by offset \
                         (cpu_affinity=0)",
                        allowed.len(),
                        if held.is_empty() {
                            "none".into()
                        } else {
                            held.join(", ")
                        }
                    )));
                };
                Some(free)
            }
        };
        let me = Entry::of_this_process(pool, workers, false, pinned.clone().unwrap_or_default());
        ledger.write(&me)?;
        drop(lock);
        let others = ledger
            .read()
            .into_iter()
            .filter(|e| e.pool != pool)
            .collect();
        let mut m = Machine {
            ledger,
            me,
            cores,
            others,
            read_at: Instant::now(),
        };
        m.record_polling();
        Ok((m, pinned))
    }

    /// Read the ledger again if it is older than [`REFRESH`].
    fn refresh(&mut self) {
        if self.read_at.elapsed() < REFRESH {
            return;
        }
        self.read_at = Instant::now();
        let me = &self.me.pool;
        self.others = self
            .ledger
            .read()
            .into_iter()
            .filter(|e| &e.pool != me)
            .collect();
        self.record_polling();
    }

    /// Say in the ledger whether this pool's caller polls, when that changed.
    fn record_polling(&mut self) {
        let polls = self.demand() < self.cores;
        if polls != self.me.caller_polls {
            self.me.caller_polls = polls;
            let _ = self.ledger.write(&self.me);
        }
    }

    /// The demand this pool counts (see the module docs).
    fn demand(&self) -> usize {
        self.me.workers + self.others.iter().map(|e| e.workers + 1).sum::<usize>()
    }

    /// How this pool's workers wait for their next command (`async_api`: the async API is in
    /// use).
    pub(super) fn worker_pace(&mut self, async_api: bool) -> Pace {
        self.refresh();
        let demand = self.demand();
        let past = if async_api {
            demand >= self.cores
        } else {
            demand > self.cores
        };
        match (past, self.others.is_empty()) {
            (false, true) => Pace::Expected,
            (true, true) => Pace::Block,
            // Other pools: never a long poll, and never past the cores' worth of pollers.
            (false, false) => Pace::Short,
            (true, false) if async_api => Pace::Block,
            (true, false) => Pace::Short,
        }
    }

    /// Whether this pool's caller may poll through a call (a core is left for it).
    pub(super) fn caller_polls(&mut self) -> bool {
        self.refresh();
        self.me.caller_polls
    }

    /// What [`crate::Pool::machine`] reports.
    pub(super) fn view(&mut self) -> MachineView {
        self.refresh();
        MachineView {
            cores: self.cores,
            demand: self.demand(),
            worker_pace: match self.worker_pace(false) {
                Pace::Expected => "expected",
                Pace::Short => "short",
                Pace::Block => "block",
            },
            caller_polls: self.me.caller_polls,
            others: (self.others.iter())
                .map(|e| {
                    (
                        e.pool.clone(),
                        e.pid,
                        e.workers,
                        e.caller_polls,
                        e.cores.clone(),
                    )
                })
                .collect(),
        }
    }

    /// Leave the ledger (the pool closes; also when the value drops).
    pub(super) fn leave(&self) {
        let _ = self.ledger.leave(&self.me.pool);
    }
}

impl Drop for Machine {
    fn drop(&mut self) {
        self.leave();
    }
}

/// The cores the affinity mask allows, in order.
pub(super) fn allowed_cores() -> Vec<usize> {
    use nix::sched::{CpuSet, sched_getaffinity};
    let Ok(set) = sched_getaffinity(nix::unistd::Pid::from_raw(0)) else {
        return vec![0];
    };
    let cores: Vec<usize> = (0..CpuSet::count())
        .filter(|&c| set.is_set(c).unwrap_or(false))
        .collect();
    if cores.is_empty() { vec![0] } else { cores }
}
