//! A worker's envs as one whole: one [`crate::Env`] each or one [`crate::EnvBlock`], how a
//! command is answered into the block, and the env calls of the call files.

use rogue_gym_ipc::PoolId;

use super::block::BlockHost;
use super::slot::{BlockOut, Slot, SlotCtx, apply};
use crate::wire::{EnvFault, calls};

/// A worker's envs: one [`Env`] each, or one [`crate::EnvBlock`] for them all.
pub(super) enum Hosted {
    Each(Vec<Slot>),
    Block(BlockHost),
}

impl Hosted {
    pub(super) fn len(&self) -> usize {
        match self {
            Hosted::Each(slots) => slots.len(),
            Hosted::Block(host) => host.len(),
        }
    }

    /// Answer one command (`kind`, with `per_env` payload words per env) into `out`.
    pub(super) fn serve(
        &mut self,
        kind: u32,
        payload: &[u64],
        per_env: usize,
        out: &mut BlockOut<'_>,
        ctx: &SlotCtx,
    ) -> Result<(), EnvFault> {
        let slots = match self {
            Hosted::Block(host) => return host.serve(kind, payload, out, ctx),
            Hosted::Each(slots) => slots,
        };
        for (j, s) in slots.iter_mut().enumerate() {
            let rec = apply(
                s,
                kind,
                &payload[j * per_env..(j + 1) * per_env],
                out.env(j),
                ctx,
            )?;
            out.finish(j, &rec);
        }
        Ok(())
    }
}

/// Answer the call requests of the worker's call file ([`calls`]), env by env.
pub(super) fn answer_calls(
    id: &PoolId,
    (index, generation): (usize, u64),
    hosted: &mut Hosted,
    first: u64,
) -> Result<(), EnvFault> {
    let fail = |env: u64, message: String| EnvFault {
        env,
        context: "a call".into(),
        message,
    };
    let requests =
        calls::take(&calls::request_path(id, index, generation)).map_err(|e| fail(first, e))?;
    let mut replies = Vec::with_capacity(requests.len());
    for (row, request) in &requests {
        let j = *row as usize;
        if j >= hosted.len() {
            return Err(fail(
                first,
                format!("call for row {row}, outside the block"),
            ));
        }
        let reply = match hosted {
            Hosted::Each(slots) => slots[j].env.call(request),
            Hosted::Block(host) => host.call(j, request),
        };
        replies.push((
            *row,
            reply.map_err(|e| fail(first + j as u64, e.to_string()))?,
        ));
    }
    let entries: Vec<(u32, &[u8])> = replies.iter().map(|(r, b)| (*r, b.as_slice())).collect();
    calls::write(
        &calls::reply_path(id, index, generation),
        &calls::encode(&entries),
    )
    .map_err(|e| fail(first, e))
}
