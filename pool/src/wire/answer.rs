//! A worker's answer to a command, typed: the kind of sample it sends (`BlockKind`) and what
//! its first words say of the rows it wrote in the batch slots (`Answer`). A sample carries
//! those words only, and for an answer of some envs their rows (`rows_of`): every answer's
//! rows are in the slots.
//!
//! Only `Answer::encode` and `Answer::decode` know how the words are packed; the worker
//! builds an answer env by env (`AnswerBuilder`), the supervisor decodes it, and decoding
//! checks every value the worker wrote, so that a worker that writes garbage is named, never
//! believed.

use crate::wire::record::EnvRecord;

/// The leading bytes of an env's extra info that say its layout (hosted envs: the typed row's
/// magic, tag and structure hash): answers whose envs share them share one layout. Python
/// reads it as `rogue_gym._native.EXTRA_HEAD`.
pub const EXTRA_HEAD: usize = 16;

/// Words at the head of an answer ([`Answer::encode`]).
pub(crate) const ANSWER_WORDS: usize = 2 + EXTRA_HEAD / 8;

/// Words of every sample a worker of `envs` envs publishes: the answer's words, then (an
/// answer of some envs, [`BlockKind::Rows`]) their number and their rows.
pub(crate) fn sample_words(envs: usize) -> usize {
    ANSWER_WORDS + 1 + envs
}

/// What a block from a worker is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum BlockKind {
    /// The worker is up (no payload).
    Ready,
    /// The answer to a reset or step: an [`Answer`] in its first words (the rows are in the
    /// slots the command named).
    Data,
    /// An env failed on the command (no data); the report is in the worker's fault file
    /// ([`crate::wire::env_fault_path`]).
    Error,
    /// The replies of an env call are written (no data).
    Call,
    /// Some envs of a [`crate::wire::Command::partial`] command, done: their rows are in their
    /// slots; the payload is the [`Answer`] of those envs, then their number, then their rows in
    /// the block ([`rows_of`]).
    Rows,
}

/// The rows an answer of kind [`BlockKind::Rows`] (or an error answer of a partial command)
/// names, checked: at most `envs` of them, each below `envs`. An error says what was wrong.
pub(crate) fn rows_of(payload: &[u64], at: usize, envs: usize) -> Result<Vec<usize>, String> {
    let n = *payload.get(at).ok_or("an answer without its rows")? as usize;
    if n > envs {
        return Err(format!("an answer naming {n} envs of a block of {envs}"));
    }
    let rows = payload
        .get(at + 1..at + 1 + n)
        .ok_or_else(|| format!("an answer naming {n} rows, cut short"))?;
    rows.iter()
        .map(|&r| {
            (r < envs as u64)
                .then_some(r as usize)
                .ok_or_else(|| format!("an answer naming row {r} of a block of {envs}"))
        })
        .collect()
}

impl BlockKind {
    /// The kind's word in the block header.
    pub(crate) fn word(self) -> u32 {
        match self {
            BlockKind::Ready => 1,
            BlockKind::Data => 2,
            BlockKind::Error => 3,
            BlockKind::Call => 4,
            BlockKind::Rows => 5,
        }
    }

    /// The kind a header word holds, if any.
    pub(crate) fn from_word(word: u32) -> Option<BlockKind> {
        Some(match word {
            1 => BlockKind::Ready,
            2 => BlockKind::Data,
            3 => BlockKind::Error,
            4 => BlockKind::Call,
            5 => BlockKind::Rows,
            _ => return None,
        })
    }
}

/// The extra info (hosted envs' infos) of an answer's envs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum AnswerExtras {
    /// No env wrote any.
    None,
    /// Every env wrote `size` bytes (1 or more) with the same first [`EXTRA_HEAD`] bytes
    /// `head`, each in its room of the slot: one typed layout, read in place.
    Uniform {
        /// Bytes of each env's extra info.
        size: usize,
        /// Their common first bytes.
        head: [u8; EXTRA_HEAD],
    },
    /// Some envs wrote some, not of one layout: each env's `extra_len` says how much.
    Mixed,
}

/// What an answer says of the rows it wrote.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Answer {
    /// Some env has a final observation in the slot (SAME_STEP).
    pub(crate) final_obs: bool,
    /// Some env's extra info did not fit its room: it travels in the answer's side file
    /// ([`crate::wire::extra_apart_path`]).
    pub(crate) apart: bool,
    /// The envs' extra info.
    pub(crate) extras: AnswerExtras,
}

const FINAL: u64 = 1;
const APART: u64 = 1 << 1;
const UNIFORM: u64 = 1 << 2;
const ANY_EXTRA: u64 = 1 << 3;
const KNOWN: u64 = FINAL | APART | UNIFORM | ANY_EXTRA;

impl Answer {
    /// The answer's words: bits, the uniform size, the uniform head.
    pub(crate) fn encode(&self) -> [u64; ANSWER_WORDS] {
        let mut words = [0u64; ANSWER_WORDS];
        words[0] = flag(self.final_obs, FINAL) | flag(self.apart, APART);
        match self.extras {
            AnswerExtras::None => {}
            AnswerExtras::Mixed => words[0] |= ANY_EXTRA,
            AnswerExtras::Uniform { size, head } => {
                words[0] |= ANY_EXTRA | UNIFORM;
                words[1] = size as u64;
                for (w, c) in words[2..].iter_mut().zip(head.chunks_exact(8)) {
                    *w = u64::from_le_bytes(c.try_into().unwrap_or([0; 8]));
                }
            }
        }
        words
    }

    /// The answer `words` hold, checked: no unknown bits, and a uniform size of 1 to `room`
    /// bytes (the env's extra-info room). An error says what was wrong.
    pub(crate) fn decode(words: &[u64], room: usize) -> Result<Answer, String> {
        let Some(&[bits, size, ..]) = words.get(..ANSWER_WORDS) else {
            return Err(format!("an answer of {} words", words.len()));
        };
        if bits & !KNOWN != 0 {
            return Err(format!("unknown bits in the answer word {bits:#x}"));
        }
        let extras = match (bits & ANY_EXTRA != 0, bits & UNIFORM != 0) {
            (false, false) => AnswerExtras::None,
            (true, false) => AnswerExtras::Mixed,
            (false, true) => {
                return Err(format!("a uniform answer without extra info ({bits:#x})"));
            }
            (true, true) => {
                let size = usize::try_from(size).unwrap_or(usize::MAX);
                if size == 0 || size > room {
                    return Err(format!(
                        "a uniform extra-info size of {size} bytes, outside 1..={room} (the room \
                         of an env)"
                    ));
                }
                let mut head = [0u8; EXTRA_HEAD];
                for (c, w) in head.chunks_exact_mut(8).zip(&words[2..ANSWER_WORDS]) {
                    c.copy_from_slice(&w.to_le_bytes());
                }
                AnswerExtras::Uniform { size, head }
            }
        };
        Ok(Answer {
            final_obs: bits & FINAL != 0,
            apart: bits & APART != 0,
            extras,
        })
    }
}

fn flag(on: bool, bit: u64) -> u64 {
    if on { bit } else { 0 }
}

/// An [`Answer`] built env by env as a worker writes its rows in place.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct AnswerBuilder {
    final_obs: bool,
    apart: bool,
    /// Envs that wrote extra info.
    extras: usize,
    /// The size and head of every env's extra info, while all are the same.
    size: usize,
    head: [u8; EXTRA_HEAD],
    mixed: bool,
}

impl AnswerBuilder {
    /// Count an env's record, `room` being its extra-info room as written.
    pub(crate) fn add(&mut self, rec: &EnvRecord, room: &[u8]) {
        self.final_obs |= rec.has_final_obs();
        self.apart |= rec.extra_apart();
        let n = rec.extra_len as usize;
        if n == 0 {
            return;
        }
        let mut head = [0u8; EXTRA_HEAD];
        let k = n.min(EXTRA_HEAD).min(room.len());
        head[..k].copy_from_slice(&room[..k]);
        if self.extras == 0 {
            (self.size, self.head) = (n, head);
        } else if self.size != n || self.head != head {
            self.mixed = true;
        }
        self.mixed |= rec.extra_apart();
        self.extras += 1;
    }

    /// The answer of a block of `envs` envs.
    pub(crate) fn finish(&self, envs: usize) -> Answer {
        let extras = match self.extras {
            0 => AnswerExtras::None,
            n if n == envs && !self.mixed && !self.apart => AnswerExtras::Uniform {
                size: self.size,
                head: self.head,
            },
            _ => AnswerExtras::Mixed,
        };
        Answer {
            final_obs: self.final_obs,
            apart: self.apart,
            extras,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::record::{FLAG_EXTRA_APART, FLAG_FINAL_OBS};
    use proptest::prelude::*;

    fn extras() -> impl Strategy<Value = AnswerExtras> {
        prop_oneof![
            Just(AnswerExtras::None),
            Just(AnswerExtras::Mixed),
            (1usize..=4096, any::<[u8; EXTRA_HEAD]>())
                .prop_map(|(size, head)| AnswerExtras::Uniform { size, head }),
        ]
    }

    proptest! {
        #[test]
        fn every_answer_survives_the_wire(
            final_obs in any::<bool>(),
            apart in any::<bool>(),
            extras in extras(),
        ) {
            let a = Answer { final_obs, apart, extras };
            prop_assert_eq!(Answer::decode(&a.encode(), 4096), Ok(a));
        }

        #[test]
        fn no_word_decodes_to_a_size_beyond_the_room(words in any::<[u64; ANSWER_WORDS]>()) {
            if let Ok(Answer { extras: AnswerExtras::Uniform { size, .. }, .. }) =
                Answer::decode(&words, 64)
            {
                prop_assert!((1..=64).contains(&size));
            }
        }

        #[test]
        fn every_block_kind_survives_the_wire(k in 1u32..=5) {
            let kind = BlockKind::from_word(k).unwrap();
            prop_assert_eq!(kind.word(), k);
        }
    }

    #[test]
    fn words_that_are_no_answer_are_refused_with_what_was_wrong() {
        let uniform = |size: u64| [ANY_EXTRA | UNIFORM, size, 0, 0];
        assert!(
            Answer::decode(&uniform(65), 64)
                .unwrap_err()
                .contains("65 bytes")
        );
        assert!(Answer::decode(&uniform(0), 64).is_err());
        assert!(Answer::decode(&uniform(u64::MAX), 64).is_err());
        assert!(
            Answer::decode(&[1 << 9, 0, 0, 0], 64)
                .unwrap_err()
                .contains("unknown bits")
        );
        assert!(Answer::decode(&[UNIFORM, 3, 0, 0], 64).is_err());
        assert!(Answer::decode(&[0, 0], 64).is_err());
        assert_eq!(BlockKind::from_word(0), None);
        assert_eq!(BlockKind::from_word(6), None);
        assert_eq!(rows_of(&[2, 0, 3], 0, 4), Ok(vec![0, 3]));
        assert!(rows_of(&[2, 0, 4], 0, 4).unwrap_err().contains("row 4"));
        assert!(rows_of(&[9, 0], 0, 4).unwrap_err().contains("9 envs"));
        assert!(rows_of(&[2, 0], 0, 4).unwrap_err().contains("cut short"));
    }

    #[test]
    fn a_block_is_uniform_only_when_every_env_wrote_one_layout_in_its_room() {
        let rec = |len: u32, flags: u32| EnvRecord {
            extra_len: len,
            flags,
            ..Default::default()
        };
        let room = [7u8; 32];
        let mut b = AnswerBuilder::default();
        b.add(&rec(20, 0), &room);
        b.add(&rec(20, FLAG_FINAL_OBS), &room);
        let a = b.finish(2);
        assert!(a.final_obs && !a.apart);
        assert_eq!(
            a.extras,
            AnswerExtras::Uniform {
                size: 20,
                head: [7; EXTRA_HEAD]
            }
        );
        assert_eq!(b.finish(3).extras, AnswerExtras::Mixed, "an env wrote none");
        let mut other = b;
        other.add(&rec(21, 0), &room);
        assert_eq!(other.finish(3).extras, AnswerExtras::Mixed, "another size");
        let mut apart = AnswerBuilder::default();
        apart.add(&rec(99, FLAG_EXTRA_APART), &room);
        let a = apart.finish(1);
        assert!(a.apart);
        assert_eq!(a.extras, AnswerExtras::Mixed);
        assert_eq!(
            AnswerBuilder::default().finish(4).extras,
            AnswerExtras::None
        );
    }
}
