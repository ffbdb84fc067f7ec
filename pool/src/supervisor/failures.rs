//! Lost workers: detecting dead and hung ones whatever they were doing, and handling each
//! per the failure policy (restart with a backoff of its own, or raise).

use std::fs;
use std::io::{Read, Seek, SeekFrom};
use std::os::unix::process::ExitStatusExt;
use std::path::PathBuf;
use std::process::ExitStatus;
use std::time::{Duration, Instant};

use super::Supervisor;
use super::link::LinkState;
use crate::config::FailurePolicy;
use crate::error::{FailureCause, PoolError, WorkerFailure};
use crate::wire::{EnvFault, env_fault_path};

/// The longest wait before a restart.
const MAX_BACKOFF: Duration = Duration::from_secs(2);

/// How long to wait before restarting a worker that failed `streak` times in a row without
/// answering a command in between: nothing for the first, then 50 ms, doubling up to
/// [`MAX_BACKOFF`] or half of `start_timeout`, whichever is less (a lost worker has
/// `start_timeout` to come back: the backoff leaves it half for its start-up and reset), so a
/// worker that cannot come up (a bad env, a full disk) cannot spin the machine before the
/// restart budget ends it. Each worker has its own streak and waits out its own backoff while
/// the others run and restart.
pub(super) fn restart_backoff(streak: u32, start_timeout: Duration) -> Duration {
    match streak {
        0 => Duration::ZERO,
        n => Duration::from_millis(50)
            .saturating_mul(1 << (n - 1).min(16))
            .min(MAX_BACKOFF)
            .min(start_timeout / 2),
    }
}

fn stderr_tail(path: &PathBuf) -> String {
    const N: u64 = 2048;
    let Ok(mut f) = fs::File::open(path) else {
        return String::new();
    };
    let len = f.metadata().map(|m| m.len()).unwrap_or(0);
    let _ = f.seek(SeekFrom::Start(len.saturating_sub(N)));
    let mut buf = Vec::new();
    let _ = f.read_to_end(&mut buf);
    String::from_utf8_lossy(&buf).into_owned()
}

fn status_parts(st: &ExitStatus) -> (Option<i32>, Option<i32>) {
    (st.code(), st.signal())
}

impl Supervisor {
    /// Detect dead and hung workers, whatever they were doing (starting, restarting, or
    /// answering a command), and handle each per policy ([`Supervisor::handle_failure`]). A failure
    /// the caller must hear of is queued in `self.faults`; only a spent restart budget, and a
    /// SIGBUS during the pool's first start, return at once.
    pub(super) fn check_liveness(&mut self) -> Result<(), PoolError> {
        for k in 0..self.workers.len() {
            let range = self.env_range(k);
            let s = &mut self.workers[k];
            if let LinkState::Down { until, then_reset } = s.state {
                if Instant::now() >= until {
                    self.respawn_now(k, then_reset)?;
                }
                continue;
            }
            let (since, starting, then_reset) = match s.state {
                LinkState::Starting { since, then_reset } => (since, true, then_reset),
                LinkState::Pending { since } => (since, false, true),
                // Restart policy: an idle worker that died is replaced now, not at its next
                // command, so that it comes back while others are waited for.
                LinkState::Idle if self.cfg.on_worker_failure == FailurePolicy::Restart => {
                    (Instant::now(), false, false)
                }
                _ => continue,
            };
            let idle = matches!(s.state, LinkState::Idle);
            let exited = match s.child.as_mut() {
                Some(ch) => ch.try_wait().ok().flatten(),
                None => None,
            };
            let limit = if starting {
                Some(self.cfg.start_timeout)
            } else {
                self.cfg.step_timeout
            };
            let lost = s.child.is_none();
            let hung = !lost && exited.is_none() && limit.is_some_and(|l| since.elapsed() > l);
            if (idle && exited.is_none()) || (!lost && exited.is_none() && !hung) {
                continue;
            }
            s.cut |= idle;
            if hung && let Some(ch) = s.child.as_mut() {
                let _ = ch.kill();
            }
            let status = match (exited, s.child.as_mut()) {
                (Some(st), _) => Some(st),
                (None, Some(ch)) => ch.wait().ok(),
                (None, None) => None,
            };
            s.child = None;
            let (code, signal) = status.as_ref().map(status_parts).unwrap_or((None, None));
            let tail = stderr_tail(&s.stderr_path);
            let fault_path = env_fault_path(&self.id, k, s.generation);
            if starting && fault_path.exists() {
                // An env that failed to build: its report goes to the caller as is. The worker
                // is respawned (not counted as a crash) so that a reset can try again.
                let fault = EnvFault::take(&fault_path).map_err(PoolError::Io)?;
                let pid = s.pid;
                self.respawn_now(k, then_reset)?;
                self.failures.must_reset = true;
                self.call.faults.push(PoolError::EnvFailed {
                    fault: Box::new(fault),
                    worker: k,
                    pid,
                });
                continue;
            }
            if starting && !self.started && !hung && signal.is_none() {
                // The pool's first start, and the worker gave up by itself (bad arguments, a
                // config it cannot read, no such program): another try would fail the same way.
                let reason = match code {
                    Some(c) => format!("exited with code {c} during start-up"),
                    None => "exited during start-up".into(),
                };
                return Err(PoolError::StartFailed {
                    worker: k,
                    reason,
                    stderr_tail: tail,
                });
            }
            let sigbus = signal == Some(nix::libc::SIGBUS);
            let failure = WorkerFailure {
                worker: k,
                env_ids: range.clone(),
                pid: s.pid,
                cause: match (hung, starting) {
                    (true, true) => FailureCause::NotReady(self.cfg.start_timeout),
                    (true, false) => FailureCause::Hung(limit.unwrap_or_default()),
                    _ => FailureCause::Died,
                },
                exit_code: code,
                signal,
                seeds: range
                    .clone()
                    .map(|i| self.book(k, i).map_or(0, |(_, seed)| seed))
                    .collect(),
                stderr_tail: tail,
                starting,
            };
            if sigbus {
                // A page of shared memory the filesystem could not give: restarting would only
                // die again. Fail the call (the pool's first start: the constructor) with the
                // numbers; a later reset() tries once more.
                let err = self.out_of_shared_memory(k, failure)?;
                if !self.started {
                    return Err(err);
                }
                self.call.faults.push(err);
                continue;
            }
            self.handle_failure(k, failure, then_reset)?;
        }
        Ok(())
    }

    /// Worker `k` was killed by SIGBUS: probably /dev/shm is full. Respawned once, not in a
    /// loop; the call is to fail with the [`PoolError::OutOfSharedMemory`] returned.
    fn out_of_shared_memory(
        &mut self,
        k: usize,
        failure: WorkerFailure,
    ) -> Result<PoolError, PoolError> {
        self.failures.deaths += 1;
        self.counts[k].restarts += 1;
        self.counts[k].last_failure = Some(failure.to_string());
        self.failures.must_reset = true;
        let err = PoolError::OutOfSharedMemory {
            failure: Box::new(failure),
            need: self.shm_need,
            room: rogue_gym_ipc::shm_room().ok(),
        };
        if self.started {
            self.respawn_now(k, false)?;
        }
        Ok(err)
    }

    /// Worker `k` failed for `cause`, found by a check of what it wrote rather than by its
    /// exit: kill it and handle the failure like a death ([`Supervisor::handle_failure`]).
    pub(super) fn lose(
        &mut self,
        k: usize,
        cause: FailureCause,
        then_reset: bool,
    ) -> Result<(), PoolError> {
        let range = self.env_range(k);
        let s = &mut self.workers[k];
        let status = s.child.take().and_then(|mut ch| {
            let _ = ch.kill();
            ch.wait().ok()
        });
        let (code, signal) = status.as_ref().map(status_parts).unwrap_or((None, None));
        s.idle();
        let failure = WorkerFailure {
            worker: k,
            env_ids: range.clone(),
            pid: s.pid,
            cause,
            exit_code: code,
            signal,
            seeds: range
                .map(|i| self.book(k, i).map_or(0, |(_, seed)| seed))
                .collect(),
            stderr_tail: stderr_tail(&self.workers[k].stderr_path),
            starting: false,
        };
        self.handle_failure(k, failure, then_reset)
    }

    /// A worker died or hung (while starting, restarting or stepping). Restart policy: count it
    /// against the budget and respawn it once its own backoff has passed (at once for a first
    /// failure; meanwhile it is [`LinkState::Down`] and the other workers go on); its envs, if
    /// an episode was cut (`then_reset`), restart theirs and are flagged. Raise policy: respawn
    /// it and queue [`PoolError::WorkerFailed`]. Either way the pool steps again after one
    /// reset.
    pub(super) fn handle_failure(
        &mut self,
        k: usize,
        failure: WorkerFailure,
        then_reset: bool,
    ) -> Result<(), PoolError> {
        self.failures.deaths += 1;
        self.call.failed_at.get_or_insert_with(Instant::now);
        let counts = &mut self.counts[k];
        counts.restarts += 1;
        counts.timeouts += u64::from(matches!(failure.cause, FailureCause::Hung(_)));
        counts.last_failure = Some(failure.to_string());
        match self.cfg.on_worker_failure {
            FailurePolicy::Raise => {
                self.failures.last_failure = Some(Box::new(failure.clone()));
                self.respawn_now(k, false)?;
                self.failures.must_reset = true;
                self.call
                    .faults
                    .push(PoolError::WorkerFailed(Box::new(failure)));
                Ok(())
            }
            FailurePolicy::Restart => {
                self.failures.restarts += 1;
                if self.failures.restarts > self.cfg.max_restarts {
                    self.failures.must_reset = true;
                    return Err(PoolError::RestartBudgetExceeded {
                        max_restarts: self.cfg.max_restarts,
                        last: Box::new(failure),
                    });
                }
                self.failures.last_failure = Some(Box::new(failure));
                let s = &mut self.workers[k];
                let backoff = restart_backoff(s.restart_streak, self.cfg.start_timeout);
                s.restart_streak = s.restart_streak.saturating_add(1);
                s.restarted |= then_reset;
                if backoff.is_zero() {
                    self.respawn_now(k, then_reset)
                } else {
                    s.state = LinkState::Down {
                        until: Instant::now() + backoff,
                        then_reset,
                    };
                    Ok(())
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn restart_backoff_doubles_from_nothing_up_to_its_cap() {
        let start = Duration::from_secs(30);
        let ms = |n| restart_backoff(n, start).as_millis();
        assert_eq!([ms(0), ms(1), ms(2), ms(3), ms(6)], [0, 50, 100, 200, 1600]);
        assert_eq!(restart_backoff(7, start), MAX_BACKOFF);
        assert_eq!(restart_backoff(u32::MAX, start), MAX_BACKOFF);
    }

    #[test]
    fn restart_backoff_leaves_half_the_start_timeout_for_the_start() {
        let start = Duration::from_millis(600);
        assert_eq!(restart_backoff(3, start), Duration::from_millis(200));
        assert_eq!(restart_backoff(4, start), Duration::from_millis(300));
        assert_eq!(restart_backoff(20, start), Duration::from_millis(300));
    }
}
