//! Where one command's answers go: the worker's rows of a batch slot, env by env
//! ([`BlockOut::env`], [`BlockOut::finish`]).

use crate::wire::answer::AnswerBuilder;
use crate::wire::record::{EnvRecord, FLAG_EXTRA_APART};
use crate::wire::slot_layout::SlotRows;

/// Where one env writes its answer to a command.
pub(crate) struct EnvOut<'a> {
    pub(crate) obs: &'a mut [u8],
    /// SAME_STEP final observation (empty in NEXT_STEP mode).
    pub(crate) fin: &'a mut [u8],
    /// Extra-info room (`EnvSpec::extra_bytes`).
    pub(crate) extra: &'a mut [u8],
    /// The env's extra info, whole; when it does not fit `extra`, the record is flagged
    /// [`FLAG_EXTRA_APART`] and the worker sends these bytes apart.
    pub(crate) info: &'a mut Vec<u8>,
}

/// Put an env's extra info `info` in its room `extra`, or flag the record
/// [`FLAG_EXTRA_APART`] when it does not fit (the worker then sends it beside the answer).
pub(crate) fn place_extra(
    rec: &mut EnvRecord,
    extra: &mut [u8],
    info: &[u8],
) -> Result<(), String> {
    let n = info.len();
    rec.extra_len = u32::try_from(n).map_err(|_| format!("{n} bytes of extra info"))?;
    match extra.get_mut(..n) {
        Some(room) => room.copy_from_slice(info),
        None => rec.flags |= FLAG_EXTRA_APART,
    }
    Ok(())
}

/// The buffers a worker reuses from command to command.
#[derive(Default)]
pub(crate) struct Scratch {
    /// One env's extra info.
    pub(crate) info: Vec<u8>,
    /// The envs whose info did not fit their room, with that info.
    pub(crate) apart: Vec<(u32, Vec<u8>)>,
    /// Where each env writes its observation first when the rows are written with streaming
    /// stores ([`super::streaming`]; one observation long), or empty: envs write their rows.
    pub(crate) stage: Vec<u8>,
}

/// Where one command's answers go: the worker's rows of the batch slot it writes.
pub(crate) struct BlockOut<'a> {
    /// The slot's rows, and the block's first env (its row `first`).
    rows: SlotRows,
    first: usize,
    /// What the answer says of its rows.
    pub(crate) answer: AnswerBuilder,
    pub(crate) obs: &'a mut [u8],
    pub(crate) final_obs: &'a mut [u8],
    pub(crate) extra: &'a mut [u8],
    pub(crate) obs_bytes: usize,
    pub(crate) final_bytes: usize,
    pub(crate) extra_bytes: usize,
    /// One env's extra info (reused from env to env).
    pub(crate) info: &'a mut Vec<u8>,
    apart: &'a mut Vec<(u32, Vec<u8>)>,
    stage: &'a mut [u8],
}

impl<'a> BlockOut<'a> {
    /// The answers of a command: rows `first..first + envs` of the slot `rows` writes, with
    /// the worker's buffers `scratch` (its `apart` list is emptied).
    ///
    /// # Safety
    /// Those rows of every area of the slot must be this worker's alone while the value lives
    /// (the supervisor neither reads nor lends them out until the command is answered, and no
    /// other worker writes them).
    pub(crate) unsafe fn in_slot(
        rows: SlotRows,
        first: usize,
        envs: usize,
        scratch: &'a mut Scratch,
    ) -> Self {
        let r = first..first + envs;
        // SAFETY: the caller's promise.
        let [obs, final_obs, extra] = unsafe {
            [
                rows.obs_rows(r.clone()),
                rows.final_rows(r.clone()),
                rows.extra_rows(r),
            ]
        };
        let layout = rows.layout();
        scratch.apart.clear();
        BlockOut {
            rows,
            first,
            answer: AnswerBuilder::default(),
            obs,
            final_obs,
            extra,
            obs_bytes: layout.obs_bytes,
            final_bytes: if layout.final_obs {
                layout.obs_bytes
            } else {
                0
            },
            extra_bytes: layout.extra_bytes,
            info: &mut scratch.info,
            apart: &mut scratch.apart,
            stage: &mut scratch.stage,
        }
    }

    /// Env `j`'s parts.
    pub(crate) fn env(&mut self, j: usize) -> EnvOut<'_> {
        let (ob, fb, xb) = (self.obs_bytes, self.final_bytes, self.extra_bytes);
        EnvOut {
            obs: if self.stage.is_empty() {
                &mut self.obs[j * ob..(j + 1) * ob]
            } else {
                &mut *self.stage
            },
            fin: &mut self.final_obs[j * fb..(j + 1) * fb],
            extra: &mut self.extra[j * xb..(j + 1) * xb],
            info: &mut *self.info,
        }
    }

    /// Write env `j`'s record; keep its info apart if the record says it did not fit.
    pub(crate) fn finish(&mut self, j: usize, rec: &EnvRecord) {
        if !self.stage.is_empty() {
            let ob = self.obs_bytes;
            super::streaming::copy(&mut self.obs[j * ob..(j + 1) * ob], self.stage);
        }
        self.rows.record(self.first + j, rec);
        let xb = self.extra_bytes;
        self.answer.add(rec, &self.extra[j * xb..(j + 1) * xb]);
        if rec.extra_apart() {
            self.apart.push((j as u32, std::mem::take(self.info)));
        }
    }

    /// The infos that did not fit their rooms, as `(row in the block, bytes)`, taken.
    pub(crate) fn take_apart(&mut self) -> Vec<(u32, Vec<u8>)> {
        std::mem::take(self.apart)
    }
}
