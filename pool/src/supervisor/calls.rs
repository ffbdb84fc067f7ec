//! Env calls: requests to chosen envs answered by their workers off the hot path (attribute
//! reads and writes, method calls, renders), through files in the pool's directory.

use super::{Pool, Supervisor};
use crate::error::PoolError;
use crate::wire::{Command, Op, calls};

/// One worker's entries of a call file: `(row in its block, bytes)`.
type Entries<'a> = Vec<(u32, &'a [u8])>;

impl Supervisor {
    /// `(env id, bytes)` entries grouped by worker.
    fn per_worker<'a>(
        &self,
        entries: &'a [(usize, Vec<u8>)],
    ) -> Result<Vec<Entries<'a>>, PoolError> {
        let mut out: Vec<Entries<'a>> = vec![Vec::new(); self.blocks.len()];
        for (env, bytes) in entries {
            let k = self
                .blocks
                .iter()
                .position(|b| b.contains(env))
                .ok_or_else(|| {
                    PoolError::Config(format!(
                        "env {env} does not exist (the pool has {} envs)",
                        self.cfg.num_envs
                    ))
                })?;
            out[k].push(((env - self.blocks[k].start) as u32, bytes.as_slice()));
        }
        Ok(out)
    }
}

impl Pool {
    /// Stage the parts of no fixed size of the next step's actions, `(env id, bytes)` each:
    /// the next step command to an env's worker carries them (in a private file beside it),
    /// and the env takes them ([`crate::Env::set_action_extra`]) just before it steps. What
    /// was staged before for those workers is replaced; a reset drops what it finds staged.
    /// This works for EnvPool-style [`Pool::send`] to some workers too.
    pub fn stage_action_extras(&mut self, extras: &[(usize, Vec<u8>)]) -> Result<(), PoolError> {
        let per_worker = self.sup.per_worker(extras)?;
        for (k, entries) in per_worker.iter().enumerate() {
            if !entries.is_empty() {
                self.sup.workers[k].action_extras = Some(calls::encode(entries));
            }
        }
        Ok(())
    }

    /// Send `requests` (`(env id, request bytes)`) to their envs ([`crate::Env::call`]) and
    /// return the replies, `(env id, reply bytes)` in the same order. Needs no outstanding
    /// async request; works before the first reset. An env's error is
    /// [`PoolError::EnvFailed`]; a worker that fails meanwhile is handled per policy and the
    /// call fails (a reset is then needed).
    pub fn call_envs(
        &mut self,
        requests: &[(usize, Vec<u8>)],
    ) -> Result<Vec<(usize, Vec<u8>)>, PoolError> {
        self.begin_call()?;
        self.all_idle(false)?;
        let per_worker = self.sup.per_worker(requests)?;
        let c = &mut self.sup;
        let mut asked = Vec::new();
        for (k, entries) in per_worker.iter().enumerate() {
            if entries.is_empty() {
                continue;
            }
            let s = &mut c.workers[k];
            calls::write(
                &calls::request_path(&c.id, k, s.generation),
                &calls::encode(entries),
            )
            .map_err(PoolError::Io)?;
            s.seq += 1;
            s.ports
                .send_cmd(s.seq, Command::new(Op::Call, 0).encode(), 0, |_| {})?;
            s.pending_now();
            asked.push((k, s.generation));
        }
        self.wait_until(|c| {
            asked.iter().all(|&(k, _)| {
                !(c.workers[k].state.coming_back() || c.workers[k].state.is_pending())
            })
        })?;
        let c = &mut self.sup;
        let mut replies = Vec::with_capacity(requests.len());
        for &(k, generation) in &asked {
            if c.workers[k].generation != generation || !c.workers[k].state.is_idle() {
                // Restarted meanwhile: its envs were rebuilt and reset; that reset's block is
                // dropped, so the caller must reset.
                c.workers[k].idle();
                c.arrived.retain(|&w| w != k);
                c.failures.must_reset = true;
                return Err(PoolError::State(format!(
                    "worker {k} failed during a call and was restarted; call reset() and retry"
                )));
            }
            let start = c.blocks[k].start;
            let got =
                calls::take(&calls::reply_path(&c.id, k, generation)).map_err(PoolError::Io)?;
            replies.extend(got.into_iter().map(|(row, b)| (start + row as usize, b)));
        }
        // Back in request order.
        let mut ordered = Vec::with_capacity(requests.len());
        for (env, _) in requests {
            let i = replies
                .iter()
                .position(|(e, _)| e == env)
                .ok_or_else(|| PoolError::State(format!("no reply from env {env} to its call")))?;
            ordered.push(replies.swap_remove(i));
        }
        Ok(ordered)
    }
}
