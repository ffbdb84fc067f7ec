//! The env threads of a worker whose envs run on threads (`concurrent.rs`): each takes jobs,
//! one env's reset or step each, from one queue, runs it with the env's lock held, writes the
//! env's rows straight into its areas of the batch slot, puts the job on the done list and
//! wakes the worker's own thread; and counts its jobs' time off the CPU.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, PoisonError, RwLock};
use std::time::{Duration, Instant};

use rogue_gym_ipc::CmdWaker;

use super::block_out::EnvOut;
use super::env_state::{EnvState, ServeCtx, apply};
use super::envs::lock;
use crate::config::AutoresetMode;
use crate::seeds::SeedSchedule;
use crate::stats::{Counter, StatsBuffer};
use crate::wire::record::EnvRecord;
use crate::wire::{EnvFault, Serve};

/// An area of memory a job writes: an env's rows of a slot, which stay mapped while the
/// command is in flight (the pool's batch buffer).
#[derive(Clone, Copy)]
pub(super) struct Area {
    pub(super) ptr: *mut u8,
    pub(super) len: usize,
}

// SAFETY: a plain area of a mapping that outlives the job; each env's areas are disjoint from
// every other env's, and one thread writes them at a time (see the module docs).
unsafe impl Send for Area {}

impl Area {
    pub(super) fn of(s: &mut [u8]) -> Area {
        Area {
            ptr: s.as_mut_ptr(),
            len: s.len(),
        }
    }

    /// # Safety
    /// The area must be live and this thread's alone while the slice lives.
    pub(super) unsafe fn slice<'a>(self) -> &'a mut [u8] {
        if self.len == 0 {
            return &mut [];
        }
        // SAFETY: the caller's promise.
        unsafe { std::slice::from_raw_parts_mut(self.ptr, self.len) }
    }
}

/// What a job needs besides its env: the serving context of the command.
pub(super) struct Ctx {
    pub(super) seeds: SeedSchedule,
    pub(super) num_envs: u64,
    pub(super) autoreset: AutoresetMode,
    pub(super) action_bytes: usize,
    pub(super) n_info: usize,
}

/// One env's reset or step.
pub(super) struct Job {
    pub(super) j: usize,
    pub(super) kind: Serve,
    pub(super) words: Vec<u64>,
    pub(super) obs: Area,
    pub(super) fin: Area,
    pub(super) extra: Area,
    pub(super) ctx: Arc<Ctx>,
}

/// A job done.
pub(super) struct Done {
    pub(super) j: usize,
    /// The env's record, and its whole extra info (it travels apart when the record says so).
    pub(super) result: Result<(EnvRecord, Vec<u8>), EnvFault>,
    pub(super) wall_ns: u64,
}

/// How often a busy env thread reads its CPU time (a system call, not a vDSO read): the time
/// its jobs spent off the CPU is counted in lumps of about this much wall time.
const CPU_READ_EVERY: Duration = Duration::from_millis(20);
/// An env thread about to wait for a job reads its CPU time when its jobs since the last read
/// took at least this long, so that the count is current whenever the envs are idle; envs
/// that take microseconds still read it once a few hundred jobs at most.
const CPU_READ_IDLE_NS: u64 = 1_000_000;

/// An env thread's count of its jobs' time on and off the CPU.
struct CpuClock {
    /// Wall time of the jobs since the last read, and when and at what CPU time it was.
    pub(super) wall_ns: u64,
    read_at: Instant,
    cpu_ns: u64,
}

impl CpuClock {
    fn new() -> CpuClock {
        CpuClock {
            wall_ns: 0,
            read_at: Instant::now(),
            cpu_ns: thread_cpu_ns(),
        }
    }

    /// A job took `wall_ns`: the jobs' time off the CPU since the last read, when it is time
    /// to read again (else 0). The thread's CPU time outside its jobs (taking them from the
    /// queue) is small and counted as the jobs'.
    fn job(&mut self, wall_ns: u64) -> u64 {
        self.wall_ns += wall_ns;
        if self.read_at.elapsed() < CPU_READ_EVERY {
            return 0;
        }
        self.read()
    }

    /// The thread is about to wait for a job: the jobs' time off the CPU since the last read,
    /// when they took at least [`CPU_READ_IDLE_NS`] (else 0).
    fn idle(&mut self) -> u64 {
        if self.wall_ns < CPU_READ_IDLE_NS {
            return 0;
        }
        self.read()
    }

    fn read(&mut self) -> u64 {
        let cpu = thread_cpu_ns();
        let wait = self.wall_ns.saturating_sub(cpu.saturating_sub(self.cpu_ns));
        (self.wall_ns, self.read_at, self.cpu_ns) = (0, Instant::now(), cpu);
        wait
    }
}

/// What the threads share.
pub(super) struct Shared {
    pub(super) envs: Arc<[Mutex<EnvState>]>,
    pub(super) jobs: Mutex<VecDeque<Job>>,
    pub(super) job_ready: Condvar,
    /// Jobs done, for the worker's own thread.
    pub(super) done: Mutex<Vec<Done>>,
    /// Wakes the worker's own thread; taken (dropped) when the worker stops, so that its port
    /// is given back even while env threads are stuck in an env's wait.
    pub(super) waker: RwLock<Option<CmdWaker>>,
    pub(super) stop: AtomicBool,
    /// The pool's counters and this worker's index in them (env threads count their time off
    /// the CPU themselves).
    pub(super) stats: Arc<StatsBuffer>,
    pub(super) me: usize,
}

pub(super) fn guard<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The CPU time of this thread, ns.
fn thread_cpu_ns() -> u64 {
    let mut ts = nix::libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid clock id and a valid out-pointer.
    unsafe { nix::libc::clock_gettime(nix::libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// Put the calling thread, and the threads it starts from now on, on batch scheduling
/// (`SCHED_BATCH`): the same share of the CPU, but a thread it wakes does not preempt the
/// thread running on that core at once. A worker whose envs wait wakes a thread per env
/// answer and per command; on a busy core the one preempted is most often the caller, whose
/// next call those answers wait for. The io workload of `benchmarks/async_pools.py` gains
/// about 7% by it (`benchmarks/results/async_pools/`). A kernel that refuses leaves the
/// worker as it was: only speed is at stake.
pub(super) fn batch_scheduling() {
    let param = nix::libc::sched_param { sched_priority: 0 };
    // SAFETY: pid 0 is the calling thread; a valid parameter block.
    let _ = unsafe { nix::libc::sched_setscheduler(0, nix::libc::SCHED_BATCH, &param) };
}

/// An env thread: jobs until the worker stops.
pub(super) fn env_thread(shared: Arc<Shared>) {
    let mut clock = CpuClock::new();
    let count = |wait_ns: u64| {
        if wait_ns > 0 {
            (shared.stats).add(shared.me, Counter::EnvWaitNs, wait_ns);
        }
    };
    loop {
        let job = {
            let mut q = guard(&shared.jobs);
            loop {
                if shared.stop.load(Ordering::Relaxed) {
                    return;
                }
                if let Some(job) = q.pop_front() {
                    break job;
                }
                let wait_ns = clock.idle();
                if wait_ns > 0 {
                    // Counted without the queue's lock, then the queue is looked at again.
                    drop(q);
                    count(wait_ns);
                    q = guard(&shared.jobs);
                    continue;
                }
                q = shared
                    .job_ready
                    .wait(q)
                    .unwrap_or_else(PoisonError::into_inner);
            }
        };
        let t0 = Instant::now();
        let mut info = Vec::new();
        let result = {
            let mut env = lock(&shared.envs[job.j]);
            let c = &job.ctx;
            let ctx = ServeCtx {
                seeds: &c.seeds,
                num_envs: c.num_envs,
                autoreset: c.autoreset,
                action_bytes: c.action_bytes,
                n_info: c.n_info,
            };
            // SAFETY: the job's areas are its env's rows, live until the worker's own thread
            // has this job's answer (it keeps the block, the pool keeps the slot), and no one
            // else touches them meanwhile.
            let out = unsafe {
                EnvOut {
                    obs: job.obs.slice(),
                    fin: job.fin.slice(),
                    extra: job.extra.slice(),
                    info: &mut info,
                }
            };
            apply(&mut env, job.kind, &job.words, out, &ctx)
        };
        let wall_ns = t0.elapsed().as_nanos() as u64;
        let done = Done {
            j: job.j,
            result: result.map(|rec| (rec, info)),
            wall_ns,
        };
        count(clock.job(wall_ns));
        guard(&shared.done).push(done);
        // A wake-up that fails is made up for by the worker's thread's timed wait.
        if let Some(waker) = &*shared.waker.read().unwrap_or_else(PoisonError::into_inner) {
            let _ = waker.wake();
        }
    }
}
