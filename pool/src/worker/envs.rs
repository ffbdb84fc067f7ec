//! A worker's envs as one whole: one [`crate::Env`] each (owned, or shared with the env
//! threads of `concurrent.rs`) or one [`crate::EnvBlock`], how a command is answered into the
//! block, and the env calls of the call files.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use rogue_gym_ipc::PoolId;

use super::block::BlockHost;
use super::block_out::BlockOut;
use super::env_state::{EnvState, ServeCtx, apply};
use crate::wire::books::Books;
use crate::wire::{EnvFault, Serve, calls};

/// A worker's envs: one [`crate::Env`] each, owned or shared with the env threads, or one
/// [`crate::EnvBlock`] for them all.
pub(super) enum WorkerEnvs {
    Each(Vec<EnvState>),
    /// One env each, each behind a lock, shared with the threads that step them
    /// (`concurrent.rs`); the worker's own thread takes an env's lock only while it is idle.
    Shared(Arc<[Mutex<EnvState>]>),
    Block(BlockHost),
}

/// Lock a shared env (a lock poisoned by a panicking env is taken all the same: the worker
/// reports the env's failure and the supervisor resets it).
pub(super) fn lock(env: &Mutex<EnvState>) -> MutexGuard<'_, EnvState> {
    env.lock().unwrap_or_else(PoisonError::into_inner)
}

impl WorkerEnvs {
    pub(super) fn len(&self) -> usize {
        match self {
            WorkerEnvs::Each(slots) => slots.len(),
            WorkerEnvs::Shared(envs) => envs.len(),
            WorkerEnvs::Block(host) => host.len(),
        }
    }

    /// Write every env's episode index and seed into copy `seq` of the books (`first`: the
    /// block's first env id), as the answer to command `seq` leaves them.
    pub(super) fn write_books(&self, books: &Books, seq: u64, first: usize) {
        let write = |j: usize, episode: u64, seed: u64| books.write(seq, first + j, episode, seed);
        match self {
            WorkerEnvs::Each(slots) => {
                for (j, s) in slots.iter().enumerate() {
                    write(j, s.episode, s.seed);
                }
            }
            WorkerEnvs::Shared(envs) => {
                for (j, s) in envs.iter().enumerate() {
                    let s = lock(s);
                    write(j, s.episode, s.seed);
                }
            }
            WorkerEnvs::Block(host) => {
                for (j, s) in host.books().iter().enumerate() {
                    write(j, s.episode, s.seed);
                }
            }
        }
    }

    /// Answer one command (`kind`, with `per_env` payload words per env) into `out`; with
    /// `only = (words, w)` (a [`crate::wire::Command::subset`] command: one word per env, the
    /// slot it is served into), only the envs whose word is `w` (those of `out`'s slot).
    /// Returns how many envs were served.
    pub(super) fn serve(
        &mut self,
        kind: Serve,
        payload: &[u64],
        per_env: usize,
        only: Option<(&[u64], u64)>,
        out: &mut BlockOut<'_>,
        ctx: &ServeCtx,
    ) -> Result<usize, EnvFault> {
        let slots = match (self, only) {
            (WorkerEnvs::Block(host), None) => {
                host.serve(kind, payload, out, ctx)?;
                return Ok(host.len());
            }
            (WorkerEnvs::Block(host), Some(_)) => {
                return Err(host.whole_block_only());
            }
            (WorkerEnvs::Shared(envs), _) => {
                let first = lock(&envs[0]).global;
                return Err(EnvFault::new(
                    first,
                    "a command",
                    "the envs run on threads: the worker's concurrent loop serves them",
                ));
            }
            (WorkerEnvs::Each(slots), _) => slots,
        };
        let mut served = 0;
        for (j, s) in slots.iter_mut().enumerate() {
            if only.is_some_and(|(o, w)| o[j] != w) {
                continue;
            }
            served += 1;
            let rec = apply(
                s,
                kind,
                &payload[j * per_env..(j + 1) * per_env],
                out.env(j),
                ctx,
            )?;
            out.finish(j, &rec);
        }
        Ok(served)
    }
}

/// The entries of one of the worker's call files, each handed to its env by `f` (env row,
/// bytes); the first error stops them, as a fault of `context` naming the env (`first` is the
/// block's first env id).
fn for_each_entry<T>(
    path: &std::path::Path,
    hosted: &mut WorkerEnvs,
    first: u64,
    context: &str,
    mut f: impl FnMut(&mut WorkerEnvs, usize, &[u8]) -> Result<T, crate::EnvError>,
) -> Result<Vec<(u32, T)>, EnvFault> {
    let fail = |env: u64, message: String| EnvFault::new(env, context, message);
    let entries = calls::take(path).map_err(|e| fail(first, e))?;
    let mut out = Vec::with_capacity(entries.len());
    for (row, bytes) in &entries {
        let j = *row as usize;
        if j >= hosted.len() {
            return Err(fail(
                first,
                format!("entry for row {row}, outside the block"),
            ));
        }
        let value = f(hosted, j, bytes).map_err(|e| fail(first + j as u64, e.to_string()))?;
        out.push((*row, value));
    }
    Ok(out)
}

/// Answer the call requests of the worker's call file ([`calls`]), env by env.
pub(super) fn answer_calls(
    id: &PoolId,
    (index, generation): (usize, u64),
    hosted: &mut WorkerEnvs,
    first: u64,
) -> Result<(), EnvFault> {
    let path = calls::request_path(id, index, generation);
    let replies = match hosted {
        // A vector env answers the whole request at once (an operation asked of every env
        // runs once).
        WorkerEnvs::Block(host) => {
            let fail = |message: String| EnvFault::new(first, "a call", message);
            let entries = calls::take(&path).map_err(fail)?;
            if let Some((row, _)) = entries.iter().find(|(r, _)| *r as usize >= host.len()) {
                return Err(fail(format!("entry for row {row}, outside the block")));
            }
            let requests: Vec<(usize, &[u8])> = entries
                .iter()
                .map(|(r, b)| (*r as usize, b.as_slice()))
                .collect();
            let replies = host.calls(&requests).map_err(|e| fail(e.to_string()))?;
            if replies.len() != entries.len() {
                return Err(fail(format!(
                    "{} replies to {} calls",
                    replies.len(),
                    entries.len()
                )));
            }
            entries.iter().map(|(r, _)| *r).zip(replies).collect()
        }
        _ => for_each_entry(&path, hosted, first, "a call", |h, j, request| match h {
            WorkerEnvs::Each(slots) => slots[j].env.call(request),
            WorkerEnvs::Shared(envs) => lock(&envs[j]).env.call(request),
            WorkerEnvs::Block(host) => host.call(j, request),
        })?,
    };
    let entries: Vec<(u32, &[u8])> = replies.iter().map(|(r, b)| (*r, b.as_slice())).collect();
    calls::write(
        &calls::reply_path(id, index, generation),
        &calls::encode(&entries),
    )
    .map_err(|message| EnvFault::new(first, "a call", message))
}

/// Hand each env its action extra of the next step, from the worker's action-extras file
/// ([`calls::action_extras_path`]).
pub(super) fn take_action_extras(
    id: &PoolId,
    (index, generation): (usize, u64),
    hosted: &mut WorkerEnvs,
    first: u64,
) -> Result<(), EnvFault> {
    let path = calls::action_extras_path(id, index, generation);
    for_each_entry(&path, hosted, first, "actions", |h, j, extra| match h {
        WorkerEnvs::Each(slots) => slots[j].env.set_action_extra(extra),
        WorkerEnvs::Shared(envs) => lock(&envs[j]).env.set_action_extra(extra),
        WorkerEnvs::Block(_) => Err(crate::EnvError::new(
            "a vector env per worker takes actions of a fixed size only",
        )),
    })?;
    Ok(())
}
