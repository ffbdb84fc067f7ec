//! What the XLA handlers step: a pool (by weak reference, so that a compiled function never
//! keeps one alive), its geometry, and the handlers' own state (the actions of a sync step
//! staged by `send` for the next `recv`, and the envs of the last async `recv`).

use std::sync::{Mutex, Weak};

use rogue_gym_pool::{Actions, EnvRecord, Pool, PoolError, RecvWant};

use super::handlers::{Buf, Outputs};

/// A pool as the XLA handlers see it.
pub(crate) struct XlaTarget {
    pool: Weak<Mutex<Option<Pool>>>,
    num_envs: usize,
    batch_size: usize,
    obs_bytes: usize,
    /// Bytes of one raw action (0: action indices).
    action_bytes: usize,
    n_info: usize,
    state: Mutex<State>,
}

#[derive(Default)]
struct State {
    /// (Sync) the actions `send` staged, in env order.
    staged: Option<Staged>,
    /// (Async) the envs of the last `recv`: a `send` without env ids answers them.
    last_ids: Vec<usize>,
    /// The records of the last `recv`'s rows.
    records: Vec<EnvRecord>,
}

enum Staged {
    Indices(Vec<i64>),
    Bytes(Vec<u8>),
}

impl Staged {
    fn as_actions(&self) -> Actions<'_> {
        match self {
            Staged::Indices(a) => Actions::Indices(a),
            Staged::Bytes(b) => Actions::Bytes(b),
        }
    }
}

impl XlaTarget {
    /// A target over `pool` (the pool's geometry as its binding knows it).
    pub(crate) fn new(
        pool: Weak<Mutex<Option<Pool>>>,
        num_envs: usize,
        batch_size: usize,
        obs_bytes: usize,
        action_bytes: usize,
        n_info: usize,
    ) -> Self {
        XlaTarget {
            pool,
            num_envs,
            batch_size,
            obs_bytes,
            action_bytes,
            n_info,
            state: Mutex::new(State::default()),
        }
    }

    /// Whether `recv` returns every env at once (EnvPool's sync mode).
    fn sync(&self) -> bool {
        self.batch_size == self.num_envs
    }

    /// Rows of a `recv`.
    pub(crate) fn rows(&self) -> usize {
        self.batch_size
    }

    /// Info values per env (the `info` output's columns).
    pub(crate) fn n_info(&self) -> usize {
        self.n_info
    }

    /// Run `f` on the open pool, with its interrupt check (which takes the GIL) set aside: an
    /// XLA thread must not wait for the GIL, which the thread that runs the compiled function
    /// may hold.
    fn with_pool<R>(&self, f: impl FnOnce(&mut Pool) -> Result<R, PoolError>) -> Result<R, String> {
        let closed = || {
            "the pool of this xla() handle is closed: make a new pool and call xla() again"
                .to_string()
        };
        let shared = self.pool.upgrade().ok_or_else(closed)?;
        let mut guard = crate::gil::lock_any(&shared);
        let pool = guard.as_mut().ok_or_else(closed)?;
        let check = pool.set_interrupt_check(None);
        let res = pool.guarded(f);
        pool.set_interrupt_check(check);
        res.map_err(|e| e.to_string())
    }

    /// `send(handle, action, env_id)`: stage a sync step's actions, or send an async one.
    pub(crate) fn send(&self, action: &Buf, env_ids: Option<&Buf>) -> Result<(), String> {
        let mut state = crate::gil::lock_any(&self.state);
        let ids: Vec<usize> = match env_ids {
            Some(b) => b.indices("env_id", self.num_envs)?,
            None if self.sync() => (0..self.num_envs).collect(),
            None if state.last_ids.is_empty() => {
                return Err(
                    "send() without env_id answers the envs of the last recv(), and there was none: pass env_id"
                        .into(),
                );
            }
            None => state.last_ids.clone(),
        };
        let rows = action.rows();
        if rows != ids.len() {
            return Err(format!(
                "send(): {rows} actions for {} env ids: give one action per env",
                ids.len()
            ));
        }
        if self.sync() {
            let mut seen = vec![false; self.num_envs];
            if ids.len() != self.num_envs
                || ids.iter().any(|&e| std::mem::replace(&mut seen[e], true))
            {
                return Err(format!(
                    "this pool steps all its {} envs at once (batch_size = num_envs): send one action per env, each env once",
                    self.num_envs
                ));
            }
        }
        let staged = self.actions(action, &ids)?;
        if self.sync() {
            state.staged = Some(staged);
            return Ok(());
        }
        self.with_pool(|p| p.send(staged.as_actions(), &ids))
    }

    /// The actions of `action` as the pool takes them: in env order for a sync step (row `r`
    /// is for env `ids[r]`), in row order for an async send.
    fn actions(&self, action: &Buf, ids: &[usize]) -> Result<Staged, String> {
        let place = |r: usize| if self.sync() { ids[r] } else { r };
        if self.action_bytes == 0 {
            let values = action.integers("action")?;
            if values.len() != ids.len() {
                return Err(format!(
                    "send(): this env takes one action index per env, got an action array of {} values for {} envs",
                    values.len(),
                    ids.len()
                ));
            }
            let mut out = vec![0i64; values.len()];
            for (r, v) in values.into_iter().enumerate() {
                out[place(r)] = v;
            }
            return Ok(Staged::Indices(out));
        }
        let bytes = action.bytes();
        let ab = self.action_bytes;
        if bytes.len() != ids.len() * ab {
            return Err(format!(
                "send(): this env's actions are {ab} bytes each, got {} bytes for {} envs: pass actions of the action space's dtype and shape",
                bytes.len(),
                ids.len()
            ));
        }
        let mut out = vec![0u8; bytes.len()];
        for r in 0..ids.len() {
            let at = place(r) * ab;
            out[at..at + ab].copy_from_slice(&bytes[r * ab..(r + 1) * ab]);
        }
        Ok(Staged::Bytes(out))
    }

    /// `recv(handle)`: step the staged sync actions, or receive the next async batch, into
    /// `outs`.
    pub(crate) fn recv(&self, outs: &mut Outputs<'_>) -> Result<(), String> {
        let mut state = crate::gil::lock_any(&self.state);
        let state = &mut *state;
        let (rows, ob) = (self.batch_size, self.obs_bytes);
        let obs = outs.obs.bytes_mut();
        // One observation's own bytes: the pool's rows may be padded past them.
        let own = obs.len() / rows.max(1);
        if obs.len() != rows * own || own > ob {
            return Err(format!(
                "recv(): the observation output has {} bytes, not {rows} rows of at most {ob}",
                obs.len()
            ));
        }
        // A sync pool's step is the receive of every env in env order (a view of its slot).
        let staged = match self.sync() {
            true => Some(
                state
                    .staged
                    .take()
                    .ok_or("recv() of a sync pool follows a send() of every env's action")?,
            ),
            false => None,
        };
        let (got, writer) = self.with_pool(|p| {
            let got = match &staged {
                Some(staged) => p.step(staged.as_actions())?,
                None => p.recv_want(RecvWant::exactly(rows))?,
            };
            let writer = got.view.and_then(|(slot, _)| p.slot_rows(slot));
            Ok((got, writer))
        })?;
        let records = &mut state.records;
        records.clear();
        match (got.view, &writer) {
            (Some((_, first)), Some(w)) => {
                // SAFETY: the view's rows, which no worker writes before the next send.
                let rows = unsafe { w.obs_rows(first..first + rows) };
                copy_rows(rows, ob, obs, own);
                records.extend((first..first + got.env_ids.len()).map(|e| w.read(e)));
            }
            _ => {
                copy_rows(&got.obs, ob, obs, own);
                records.extend_from_slice(&got.records);
            }
        }
        outs.write(&got.env_ids, records, self.n_info)?;
        state.last_ids = got.env_ids;
        Ok(())
    }
}

/// Copy the first `own` bytes of each `stride`-byte row of `src` into `dst`'s rows.
fn copy_rows(src: &[u8], stride: usize, dst: &mut [u8], own: usize) {
    if own == stride {
        dst.copy_from_slice(&src[..dst.len()]);
        return;
    }
    for (d, s) in dst.chunks_exact_mut(own).zip(src.chunks_exact(stride)) {
        d.copy_from_slice(&s[..own]);
    }
}
