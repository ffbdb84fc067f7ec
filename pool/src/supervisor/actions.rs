//! The actions of a step as the pool takes them ([`Actions`]), and their one check
//! ([`Actions::check`]), made on the caller's side before anything is sent: the workers trust
//! what arrives.

use std::ops::Range;

use crate::env::EnvSpec;
use crate::error::PoolError;

/// The actions of a step, one per env: indices `0..num_actions`, or `EnvSpec::action_bytes`
/// raw bytes each (envs that decode their own actions, such as hosted gymnasium envs).
#[derive(Debug, Clone, Copy)]
pub enum Actions<'a> {
    /// One index per env.
    Indices(&'a [i64]),
    /// `action_bytes` bytes per env, env after env.
    Bytes(&'a [u8]),
}

impl<'a> From<&'a [i64]> for Actions<'a> {
    fn from(a: &'a [i64]) -> Self {
        Actions::Indices(a)
    }
}

impl<'a> From<&'a Vec<i64>> for Actions<'a> {
    fn from(a: &'a Vec<i64>) -> Self {
        Actions::Indices(a)
    }
}

impl<'a, const N: usize> From<&'a [i64; N]> for Actions<'a> {
    fn from(a: &'a [i64; N]) -> Self {
        Actions::Indices(a)
    }
}

impl<'a> Actions<'a> {
    /// The actions of rows `rows` (`action_bytes`: bytes per action, for `Bytes`).
    pub(crate) fn rows(self, rows: Range<usize>, action_bytes: usize) -> Actions<'a> {
        match self {
            Actions::Indices(a) => Actions::Indices(&a[rows]),
            Actions::Bytes(b) => {
                Actions::Bytes(&b[rows.start * action_bytes..rows.end * action_bytes])
            }
        }
    }

    /// Check one action per row for an env of `spec`, row `r` being env `env_of(r)`'s: `rows`
    /// indices in `0..num_actions`, or `rows x action_bytes` bytes; the error names the env
    /// and the value, or the lengths.
    pub fn check(
        self,
        spec: &EnvSpec,
        rows: usize,
        env_of: impl Fn(usize) -> usize,
    ) -> Result<(), PoolError> {
        match self {
            Actions::Indices(a) if spec.action_bytes == 0 => {
                if a.len() != rows {
                    return Err(PoolError::BadActionsLength {
                        expected: rows,
                        got: a.len(),
                    });
                }
                validate_actions(a, (0..rows).map(env_of), spec.num_actions)
            }
            Actions::Bytes(b) if spec.action_bytes > 0 => {
                if b.len() != rows * spec.action_bytes {
                    return Err(PoolError::BadBuffer {
                        what: "action bytes",
                        expected: rows * spec.action_bytes,
                        got: b.len(),
                    });
                }
                Ok(())
            }
            Actions::Indices(_) => Err(PoolError::Config(format!(
                "this env takes actions as {} raw bytes each, not indices",
                spec.action_bytes
            ))),
            Actions::Bytes(_) => Err(PoolError::Config(format!(
                "this env takes action indices 0..{}, not raw bytes",
                spec.num_actions
            ))),
        }
    }
}

/// Check that every action is in `0..num_actions`; the error names the env and the value.
pub fn validate_actions(
    actions: &[i64],
    env_ids: impl Iterator<Item = usize>,
    num_actions: usize,
) -> Result<(), PoolError> {
    // The usual case, in one pass (the error path below finds the env); about 1 us for 4,096
    // actions (`cargo bench -p rogue-gym-pool --bench actions`).
    if actions.iter().all(|&a| (a as u64) < num_actions as u64) {
        return Ok(());
    }
    for (a, env) in actions.iter().zip(env_ids) {
        if *a < 0 || *a as u64 >= num_actions as u64 {
            return Err(PoolError::BadAction {
                env,
                value: *a,
                num_actions,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn actions_are_validated_with_env_and_value() {
        assert!(validate_actions(&[0, 10, 5], 0..3, 11).is_ok());
        let e = validate_actions(&[0, 11], 4..6, 11).unwrap_err();
        assert_eq!(
            e.to_string(),
            "env 5: action 11 is out of range; valid actions are 0 to 10 (range(11))"
        );
        assert!(matches!(
            validate_actions(&[-1], 0..1, 11),
            Err(PoolError::BadAction {
                env: 0,
                value: -1,
                ..
            })
        ));
    }
}
