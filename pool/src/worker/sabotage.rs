//! A worker's misdeed on cue ([`crate::wire::sabotage`]): the test hook of the caller's checks.
//! Each misdeed is what a worker running a corrupting C extension, or killed at the wrong
//! moment, could leave; the caller must name the worker, never believe the value.

use std::os::fd::AsRawFd;

use super::Worker;
use crate::wire::answer::{Answer, AnswerExtras, EXTRA_HEAD};
use crate::wire::sabotage::Misdeed;
use crate::wire::slot_layout::Flag;
use crate::wire::{calls, extra_apart_path};

impl Worker<'_> {
    /// The misdeed to commit in the answer to this worker's `count`-th reset or step, if any.
    pub(super) fn misdeed(&self, count: u64) -> Option<Misdeed> {
        let s = self.cfg.sabotage.as_ref()?;
        (s.worker == self.args.index && s.at == count).then(|| s.what.clone())
    }

    /// Commit `m` in the answer to command `seq` (`(target, j)`: the first env it served is
    /// row `j` of the block, its rows written in slot `target - 1`), its books written, its
    /// answer words not yet encoded.
    pub(super) fn commit(
        &self,
        m: &Misdeed,
        seq: u64,
        (target, j): (usize, usize),
        answer: &mut Answer,
    ) {
        let first = self.first_env + j;
        // The slot this command wrote; only this worker's rows touched.
        let rows = self.slot_rows(target as u64);
        match m {
            Misdeed::ExtraSize { size } => {
                answer.extras = AnswerExtras::Uniform {
                    size: *size as usize,
                    head: [0; EXTRA_HEAD],
                };
            }
            Misdeed::ApartRow { row } => {
                let path = extra_apart_path(&self.id, self.args.index, self.args.generation, seq);
                let _ = calls::write(&path, &calls::encode(&[(*row, b"x")]));
                answer.apart = true;
            }
            Misdeed::Episode { episode } => {
                for j in 0..self.block_envs {
                    self.books.write(seq, self.first_env + j, *episode, 0);
                }
            }
            Misdeed::FlagByte { byte } => rows.write_flag_byte(Flag::Terminated, first, *byte),
            Misdeed::InfoBytes { bytes } => {
                // SAFETY: this worker's first env's room, as above.
                let room = unsafe { rows.extra_rows(first..first + 1) };
                let n = bytes.len().min(room.len());
                room[..n].copy_from_slice(&bytes[..n]);
                rows.write_extra_len(first, n as u32);
                answer.extras = AnswerExtras::Mixed;
            }
            Misdeed::Truncate => {
                let fd = self.args.shared_fds[0];
                let path = format!("/proc/{}/fd/{fd}", self.args.ppid);
                let done = std::fs::OpenOptions::new()
                    .write(true)
                    .open(&path)
                    .and_then(|f| {
                        let r = nix::unistd::ftruncate(&f, 0).map_err(std::io::Error::from);
                        eprintln!("sabotage: truncate {path} (fd {}): {r:?}", f.as_raw_fd());
                        r
                    });
                eprintln!("sabotage: truncating the batch buffer: {done:?}");
            }
            Misdeed::DieMidWrite => {
                let _ = nix::sys::signal::raise(nix::sys::signal::Signal::SIGKILL);
            }
        }
    }
}
