//! A command from the supervisor to a worker, typed: [`Command`] and its word on the wire.
//!
//! The command header's `kind` word holds the operation in bits 0..8, the observation target
//! in bits 8..16 and four flags above. Only [`Command::encode`] and [`Command::decode`] know
//! that packing; both sides build and read commands as structs.

/// What a command asks of a worker.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Op {
    /// Reset (some of) the block's envs; payload: an episode index per env, or
    /// [`super::KEEP_EPISODE`].
    Reset,
    /// Step the block's envs; payload: the actions' words per env.
    Step,
    /// Exit cleanly.
    Close,
    /// Call into envs, off the hot path ([`super::calls`]); no payload.
    Call,
}

/// The two commands that the envs serve, with a payload per env.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Serve {
    /// [`Op::Reset`].
    Reset,
    /// [`Op::Step`].
    Step,
}

/// One command, as the supervisor sends it and the worker reads it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Command {
    /// The operation.
    pub op: Op,
    /// The batch slot every env of the command writes its rows in, `s + 1` for slot `s` (0:
    /// none, for a command that serves no env, or one whose envs name their slots: `subset`).
    pub target: u32,
    /// (reset) Re-read the seed schedule from the config file first.
    pub reload_seeds: bool,
    /// (step) Hand the envs the parts of their actions of no fixed size, in the worker's
    /// action-extras file ([`super::calls::action_extras_path`]), before they step.
    pub action_extras: bool,
    /// (reset, step) Each env has a slot of its own, and only some envs are served (the async
    /// API serves envs, not blocks, and each env's rows alternate between the slots): the
    /// payload carries, after the per-env words, one word per env of the block, `s + 1` for an
    /// env served into slot `s`, 0 for one left as it is.
    pub subset: bool,
    /// How to wait for the next command after answering this one.
    pub pace: Pace,
    /// (step, a worker whose envs run on threads) Answer each env as it finishes ([`super::answer::BlockKind::Rows`]), and take further commands for other envs
    /// meanwhile; without it, one answer when every env of the command is done.
    pub partial: bool,
}

/// How a worker waits for its next command after answering one (the supervisor decides, from
/// the machine's booking: `supervisor/machine.rs`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub(crate) enum Pace {
    /// Poll for the gap the caller usually leaves between an answer and the next command (up
    /// to 2 ms): a tight loop's next command finds the worker polling, no wake-up paid.
    #[default]
    Expected,
    /// Poll for the pool's base budget only, then block: other pools share the machine, and a
    /// long poll takes a core from a process with work.
    Short,
    /// Block at once: the async API on a machine with no core to spare (pollers there take the
    /// CPU from the workers with work, and first-ready-first-served then serves the pollers'
    /// envs again and again).
    Block,
}

const OP_BITS: u32 = 0xff;
const TARGET_SHIFT: u32 = 8;
const TARGET_MASK: u32 = 0xff << TARGET_SHIFT;
const RELOAD_SEEDS: u32 = 1 << 16;
const ACTION_EXTRAS: u32 = 1 << 17;
const SUBSET: u32 = 1 << 18;
const PACE_SHIFT: u32 = 19;
const PACE_MASK: u32 = 0b11 << PACE_SHIFT;
const PARTIAL: u32 = 1 << 21;
const KNOWN: u32 =
    OP_BITS | TARGET_MASK | RELOAD_SEEDS | ACTION_EXTRAS | SUBSET | PACE_MASK | PARTIAL;

impl Command {
    /// A command with no flags set.
    pub(crate) fn new(op: Op, target: u32) -> Command {
        Command {
            op,
            target,
            reload_seeds: false,
            action_extras: false,
            subset: false,
            pace: Pace::Expected,
            partial: false,
        }
    }

    /// The command's word on the wire. `target` must fit 8 bits
    /// ([`super::MAX_BATCH_SLOTS`] is far below).
    pub(crate) fn encode(self) -> u32 {
        debug_assert!(self.target <= TARGET_MASK >> TARGET_SHIFT);
        let op = match self.op {
            Op::Reset => 1,
            Op::Step => 2,
            Op::Close => 3,
            Op::Call => 4,
        };
        op | ((self.target << TARGET_SHIFT) & TARGET_MASK)
            | flag(self.reload_seeds, RELOAD_SEEDS)
            | flag(self.action_extras, ACTION_EXTRAS)
            | flag(self.subset, SUBSET)
            | flag(self.partial, PARTIAL)
            | (match self.pace {
                Pace::Expected => 0,
                Pace::Short => 1,
                Pace::Block => 2,
            } << PACE_SHIFT)
    }

    /// The command a word on the wire holds; an error naming the word if it holds none.
    pub(crate) fn decode(word: u32) -> Result<Command, String> {
        let op = match word & OP_BITS {
            1 => Op::Reset,
            2 => Op::Step,
            3 => Op::Close,
            4 => Op::Call,
            k => return Err(format!("unknown command kind {k} (word {word:#x})")),
        };
        if word & !KNOWN != 0 {
            return Err(format!("unknown command flags in word {word:#x}"));
        }
        let pace = match (word & PACE_MASK) >> PACE_SHIFT {
            0 => Pace::Expected,
            1 => Pace::Short,
            2 => Pace::Block,
            p => return Err(format!("unknown pace {p} in word {word:#x}")),
        };
        Ok(Command {
            op,
            target: (word & TARGET_MASK) >> TARGET_SHIFT,
            reload_seeds: word & RELOAD_SEEDS != 0,
            action_extras: word & ACTION_EXTRAS != 0,
            subset: word & SUBSET != 0,
            pace,
            partial: word & PARTIAL != 0,
        })
    }

    /// The envs' part of the command: [`Serve`] for a reset or a step, else `None`.
    pub(crate) fn serve(self) -> Option<Serve> {
        match self.op {
            Op::Reset => Some(Serve::Reset),
            Op::Step => Some(Serve::Step),
            Op::Close | Op::Call => None,
        }
    }
}

/// The sequence number of the next command to a worker whose last received answer was
/// `delivered`: `seq + 1`, or `seq + 2` where that would write the copy of the episode books
/// the supervisor reads (the worker writes the copy of its command's parity:
/// [`super::books`]).
pub(crate) fn next_seq(seq: u64, delivered: Option<u64>) -> u64 {
    match delivered {
        Some(d) if (seq + 1) % 2 == d % 2 => seq + 2,
        _ => seq + 1,
    }
}

fn flag(on: bool, bit: u32) -> u32 {
    if on { bit } else { 0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn op() -> impl Strategy<Value = Op> {
        prop_oneof![
            Just(Op::Reset),
            Just(Op::Step),
            Just(Op::Close),
            Just(Op::Call)
        ]
    }

    proptest! {
        #[test]
        fn every_command_survives_the_wire(
            op in op(),
            target in 0u32..=super::super::MAX_BATCH_SLOTS as u32,
            flags in any::<[bool; 4]>(),
            pace in prop_oneof![Just(Pace::Expected), Just(Pace::Short), Just(Pace::Block)],
        ) {
            let c = Command {
                op,
                target,
                reload_seeds: flags[0],
                action_extras: flags[1],
                subset: flags[2],
                pace,
                partial: flags[3],
            };
            prop_assert_eq!(Command::decode(c.encode()), Ok(c));
        }
    }

    #[test]
    fn a_word_that_is_no_command_is_refused_with_the_word() {
        assert!(
            Command::decode(0)
                .unwrap_err()
                .contains("unknown command kind 0")
        );
        assert!(Command::decode(9).unwrap_err().contains("kind 9"));
        assert!(
            Command::decode(2 | (1 << 25))
                .unwrap_err()
                .contains("flags")
        );
        assert!(
            Command::decode(2 | (3 << 19))
                .unwrap_err()
                .contains("pace 3")
        );
    }
}
